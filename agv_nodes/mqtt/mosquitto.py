"""mosquitto, the real broker: started on a free 127.0.0.1 port with a generated config.

Plants run mosquitto (the Debian package), so the launcher and the tests run it too wherever it
is installed, and the embedded amqtt broker (`agv_nodes.mqtt.broker`) only where it is not.
`Mosquitto` writes a config into a private temporary directory (one listener, no persistence,
its log in a file there), starts `mosquitto -c` through the launcher's child wrapper (so the
broker dies with the process that started it, SIGKILL included) and waits until the port
listens. It can serve TLS (mqtts://, a CA, the broker's certificate and key, optionally
requiring client certificates) and user names with passwords (a mosquitto password file it
writes itself, PBKDF2-SHA512 as `mosquitto_passwd` does; no password reaches argv or a log).

mosquitto cannot listen on port 0 and report the port it got, so a free port is found first and
the start is retried on another one when something took it in between.
"""

from __future__ import annotations

import base64
from collections.abc import Mapping
from dataclasses import dataclass
import hashlib
import os
from pathlib import Path
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import time

from agv_nodes.mqtt.address import format_mqtt_url

HOST = '127.0.0.1'
CHILD = 'agv_nodes.graph.child'  # dies with the process that started it (PR_SET_PDEATHSIG)
_PBKDF2_ROUNDS = 101  # mosquitto_passwd's default for $7$ (PBKDF2-SHA512)
_START_ATTEMPTS = 3


def find_mosquitto() -> str | None:
    """Return the mosquitto executable, or None when it is not installed.

    Debian installs it in /usr/sbin, which a user's PATH may lack.
    """
    return shutil.which('mosquitto', path=f'{os.environ.get("PATH", "")}:/usr/sbin')


def password_line(username: str, password: str, salt: bytes | None = None) -> str:
    """Return one mosquitto password-file line: `user:$7$rounds$salt$hash` (PBKDF2-SHA512)."""
    if not username or ':' in username or '\n' in username:
        raise ValueError(f'user name {username!r}: give a non-empty name without ":" or newline')
    salt = os.urandom(12) if salt is None else salt
    digest = hashlib.pbkdf2_hmac('sha512', password.encode(), salt, _PBKDF2_ROUNDS)
    return (f'{username}:$7${_PBKDF2_ROUNDS}${base64.b64encode(salt).decode()}$'
            f'{base64.b64encode(digest).decode()}')


@dataclass(frozen=True)
class BrokerTls:
    """The broker's side of TLS.

    The CA its clients' certificates are checked against, its own certificate and key, and
    whether a client must show a certificate.
    """

    ca_file: Path
    cert_file: Path
    key_file: Path
    require_certificate: bool = False


def free_port(host: str = HOST) -> int:
    """Return a port nobody listens on now (another process may take it before it is used)."""
    with socket.socket() as probe:
        probe.bind((host, 0))
        return int(probe.getsockname()[1])


class Mosquitto:
    """A private mosquitto on `host`, started by `start()` and ended by `stop()`.

    `passwords` (user name -> password) turns anonymous access off: only those users connect.
    `tls` makes the one listener TLS (the URL mqtts://). Usable as a context manager. The
    parent-death signal is tied to the thread that calls `start()`: start it from a thread
    that lives as long as the broker should (the main thread, as the launcher does).
    """

    def __init__(self, host: str = HOST, port: int = 0, tls: BrokerTls | None = None,
                 passwords: Mapping[str, str] | None = None, start_timeout_s: float = 10.0,
                 executable: str | None = None) -> None:
        """Configure; nothing runs before `start()`. port 0: a free one."""
        self.host = host
        self.name = 'mosquitto'
        self.tls = tls
        self._requested_port = port
        self._passwords = dict(passwords or {})
        self._start_timeout_s = start_timeout_s
        self._executable = executable
        self._dir: Path | None = None
        self._process: subprocess.Popen | None = None
        self.port: int | None = None

    @property
    def url(self) -> str:
        """mqtt[s]://HOST:PORT of the running broker."""
        if self.port is None:
            raise RuntimeError('mosquitto is not running')
        return format_mqtt_url(self.host, self.port, tls=self.tls is not None)

    @property
    def log_path(self) -> Path | None:
        """Return mosquitto's log file while it runs (why it refused someone)."""
        return None if self._dir is None else self._dir / 'mosquitto.log'

    def start(self) -> str:
        """Start mosquitto, wait until its port listens and return its URL.

        RuntimeError in one line when mosquitto is not installed, exits (its last log line) or
        does not listen within start_timeout_s.
        """
        if self._process is not None:
            raise RuntimeError('mosquitto is already started')
        executable = self._executable or find_mosquitto()
        if executable is None:
            raise RuntimeError('mosquitto is not installed (the Debian package mosquitto; '
                               './agv.sh test installs it as root)')
        self._dir = Path(tempfile.mkdtemp(prefix='agv_mosquitto_'))
        try:
            for attempt in range(_START_ATTEMPTS):
                port = self._requested_port or free_port(self.host)
                if self._try_start(executable, port):
                    self.port = port
                    return self.url
                if self._requested_port or attempt == _START_ATTEMPTS - 1:
                    raise RuntimeError(f'mosquitto on {self.host}:{port} did not start: '
                                       f'{self._last_log_line()}')
        except BaseException:
            self._cleanup()
            raise
        raise AssertionError('not reached')

    def stop(self, timeout_s: float = 5.0) -> None:
        """Stop mosquitto (SIGTERM, SIGKILL after timeout_s) and remove its directory."""
        process = self._process
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout_s)
        self._cleanup()

    def __enter__(self) -> Mosquitto:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def config_text(self, port: int) -> str:
        """Return the mosquitto.conf this broker runs with (paths inside its directory)."""
        assert self._dir is not None
        lines = [f'listener {port} {self.host}', 'persistence false',
                 f'log_dest file {self._dir / "mosquitto.log"}',
                 'log_type error', 'log_type warning', 'log_type notice', 'log_type information',
                 'connection_messages true', 'max_queued_messages 100000',
                 # as root mosquitto would switch to the user `mosquitto`, who cannot read the
                 # files in this private directory
                 f'user {pwd.getpwuid(os.getuid()).pw_name}']
        if self._passwords:
            lines += ['allow_anonymous false', f'password_file {self._dir / "passwords"}']
        else:
            lines.append('allow_anonymous true')
        if self.tls is not None:
            lines += [f'cafile {self.tls.ca_file}', f'certfile {self.tls.cert_file}',
                      f'keyfile {self.tls.key_file}',
                      f'require_certificate {str(self.tls.require_certificate).lower()}']
        return '\n'.join(lines) + '\n'

    def _try_start(self, executable: str, port: int) -> bool:
        assert self._dir is not None
        if self._passwords:
            passwords = self._dir / 'passwords'
            passwords.write_text(''.join(password_line(user, password) + '\n'
                                         for user, password in self._passwords.items()))
            passwords.chmod(0o600)
        conf = self._dir / 'mosquitto.conf'
        conf.write_text(self.config_text(port))
        self._process = subprocess.Popen(
            [sys.executable, '-m', CHILD, str(os.getpid()), executable, '-c', str(conf)],
            cwd=self._dir, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + self._start_timeout_s
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                self._process = None
                return False
            if self._listening(port):
                return True
            time.sleep(0.02)
        self._process.kill()
        self._process.wait()
        self._process = None
        raise RuntimeError(f'mosquitto did not listen on {self.host}:{port} within '
                           f'{self._start_timeout_s:g} s')

    def _listening(self, port: int) -> bool:
        # mosquitto logs `running` once its sockets listen: read from its log, so no probe
        # connection shows up there as a failed client
        log = self.log_path
        try:
            text = log.read_text(errors='replace') if log is not None else ''
        except OSError:
            return False
        return f'listen socket on port {port}' in text and ' running' in text

    def _last_log_line(self) -> str:
        log = self.log_path
        try:
            lines = log.read_text(errors='replace').splitlines() if log is not None else []
        except OSError:
            lines = []
        lines = [line for line in lines if line.strip()]
        return lines[-1].split(': ', 1)[-1] if lines else 'it exited without a log line'

    def _cleanup(self) -> None:
        self._process = None
        self.port = None
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None
