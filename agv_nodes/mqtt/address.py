"""Where a broker is and how to reach it: mqtt[s]:// URLs and a link's TLS files and credentials.

A URL names the broker only (scheme, host, port): it is printed in logs and on the launcher's
console, so a user name or password in it is refused; they travel apart (`LinkSecurity`), the
password read from a file or an environment variable by the node that connects.
"""

from dataclasses import dataclass, field
import os
from urllib.parse import urlsplit

DEFAULT_PORT = 1883
DEFAULT_TLS_PORT = 8883
ENV_URL = 'AGV_MQTT_URL'  # the broker a node or launch uses when none is named
_URL_FORM = 'expected mqtt://host[:port] or mqtts://host[:port]'


def parse_mqtt_url(url: str) -> tuple[str, int]:
    """Return (host, port) of an mqtt[s]://host[:port] URL; ValueError says what is wrong.

    The port defaults to 1883 (mqtts: 8883). Credentials in the URL are refused: URLs are
    printed in logs; a user name and password are given apart (`LinkSecurity`).
    """
    if not url.strip():
        raise ValueError(f'empty; {_URL_FORM}')
    if url != url.strip():
        raise ValueError(f'leading or trailing blanks; {_URL_FORM}')
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme in ('ssl', 'tls', 'wss', 'ws'):
        raise ValueError(f'{scheme}:// is not supported; {_URL_FORM}')
    if scheme not in ('mqtt', 'mqtts') or not url.lower().startswith(f'{scheme}://'):
        raise ValueError(f'not an mqtt:// URL; {_URL_FORM}')
    if parts.username is not None or parts.password is not None:
        raise ValueError('a user name or password in the URL is refused (URLs are logged): '
                         'give them as parameters, the password from a file')
    if parts.path not in ('', '/') or parts.query or parts.fragment:
        raise ValueError(f'unexpected path, query or fragment; {_URL_FORM}')
    if not parts.hostname:
        raise ValueError(f'no host; {_URL_FORM}')
    try:
        port = parts.port
    except ValueError:
        text = parts.netloc.rpartition(':')[2]
        raise ValueError(f'port {text!r} is not a number 1-65535') from None
    if port is None:
        return parts.hostname, DEFAULT_TLS_PORT if scheme == 'mqtts' else DEFAULT_PORT
    if port == 0:
        raise ValueError('port 0 is not a port one can connect to; give 1-65535')
    return parts.hostname, port


def uses_tls(url: str) -> bool:
    """Return True for an mqtts:// URL (checked by parse_mqtt_url first)."""
    return url.lower().startswith('mqtts://')


def format_mqtt_url(host: str, port: int, tls: bool = False) -> str:
    """Return the canonical mqtt[s]://host:port (IPv6 literals in brackets)."""
    scheme = 'mqtts' if tls else 'mqtt'
    return f'{scheme}://[{host}]:{port}' if ':' in host else f'{scheme}://{host}:{port}'


@dataclass(frozen=True)
class LinkSecurity:
    """TLS files and credentials of one link (all optional; the password is never printed).

    ca_file: the CA that signed the broker's certificate ('' : the system's CAs); cert_file and
    key_file: this client's certificate and key, for a broker that requires one. They apply to
    an mqtts:// URL only; given with mqtt:// they are refused, not ignored.
    """

    ca_file: str = ''
    cert_file: str = ''
    key_file: str = ''
    username: str = ''
    password: str = field(default='', repr=False)

    @property
    def tls_files(self) -> bool:
        """Return True when any TLS file is named."""
        return bool(self.ca_file or self.cert_file or self.key_file)


ENV_PASSWORD = 'AGV_MQTT_PASSWORD'  # the password when no password file is named


def read_password(password_file: str) -> str:
    """Return the link's password: the first line of password_file, else AGV_MQTT_PASSWORD.

    Never from argv (other users see a process's arguments) nor the URL (it is logged). No file
    and no variable: '' (no password). ValueError names the file when it cannot be read or its
    first line is empty.
    """
    if not password_file:
        return os.environ.get(ENV_PASSWORD, '')
    try:
        with open(password_file, encoding='utf-8') as stream:
            password = stream.readline().rstrip('\r\n')
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f'password file {password_file}: cannot read it ({exc})') from None
    if not password:
        raise ValueError(f'password file {password_file}: its first line is empty')
    return password
