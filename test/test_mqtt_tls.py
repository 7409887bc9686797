"""TLS (mqtts://, CA and client certificates) and user names with passwords, against mosquitto.

The CA, the broker's and the clients' certificates are made here (test/mqtt_broker.py TestCa);
mosquitto checks them and the passwords (its own password file, hashed as mosquitto_passwd
does), so what is accepted or refused is mosquitto's judgement, not the client's. Each refusal
must come back from connect() at once as one line naming the broker and the reason.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import logging
import queue

from mqtt_broker import TestCa, require_mosquitto
import pytest

from agv_nodes.mqtt.address import ENV_PASSWORD, LinkSecurity, read_password
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.mqtt.mosquitto import Mosquitto

pytestmark = [pytest.mark.wall_clock, pytest.mark.timeout(60)]

WAIT_S = 10.0  # upper bound for a connection or message; refusals must come well before it
USER, PASSWORD = 'truck_agv1', 'not-in-any-argv'


@pytest.fixture(scope='module')
def ca(tmp_path_factory) -> TestCa:
    return TestCa(tmp_path_factory.mktemp('ca'))


@pytest.fixture(scope='module')
def client_pair(ca):
    return ca.issue('agv1', server=False)


@pytest.fixture(scope='module')
def broker(ca) -> Iterator[Mosquitto]:
    """Mosquitto with TLS, client certificates required, and one user."""
    require_mosquitto()
    with Mosquitto(tls=ca.broker_tls(require_certificate=True),
                   passwords={USER: PASSWORD}) as running:
        yield running


@pytest.fixture
def good(ca, client_pair) -> LinkSecurity:
    return LinkSecurity(ca_file=str(ca.ca_file), cert_file=str(client_pair.cert),
                        key_file=str(client_pair.key), username=USER, password=PASSWORD)


@pytest.fixture
def links() -> Iterator[Callable[..., MqttLink]]:
    made: list[MqttLink] = []

    def make(url: str, client_id: str, security: LinkSecurity) -> MqttLink:
        link = MqttLink(url, client_id, security=security, reconnect_min_s=0.1,
                        reconnect_max_s=0.5)
        made.append(link)
        return link

    yield make
    for link in made:
        link.close()


def _refusal(make: Callable[[], MqttLink]) -> str:
    link = make()
    with pytest.raises(ConnectionError) as raised:
        link.connect(timeout=WAIT_S)
    message = str(raised.value)
    assert '\n' not in message
    return message


def test_tls_with_certificate_and_password_carries_messages(broker, links, good):
    """A client with the CA, its certificate and the password exchanges QoS 1 messages."""
    assert broker.url.startswith('mqtts://127.0.0.1:')
    truck, master = links(broker.url, 'agv1', good), links(broker.url, 'master', good)
    truck.connect(timeout=WAIT_S)
    master.connect(timeout=WAIT_S)
    orders: queue.Queue[tuple[str, bytes]] = queue.Queue()
    assert truck.subscribe('uagv/v2/m/agv1/order', 1, lambda t, p: orders.put((t, p)))
    assert master.publish('uagv/v2/m/agv1/order', b'{"orderId": "o1"}', qos=1)
    assert orders.get(timeout=WAIT_S) == ('uagv/v2/m/agv1/order', b'{"orderId": "o1"}')


def test_a_broker_signed_by_another_ca_is_refused(broker, links, good, tmp_path):
    """Trusting another CA: the broker's certificate is not trusted, said in one line."""
    other = TestCa(tmp_path / 'other', 'other CA')
    message = _refusal(lambda: links(broker.url, 'agv1', LinkSecurity(
        ca_file=str(other.ca_file), cert_file=good.cert_file, key_file=good.key_file,
        username=USER, password=PASSWORD)))
    assert message.startswith(f'MQTT broker {broker.url} refused client ')
    assert 'TLS: the broker certificate is not trusted' in message, message


def test_no_client_certificate_where_one_is_required_is_refused(broker, links, good):
    """Without a client certificate mosquitto ends the handshake; the link says why."""
    message = _refusal(lambda: links(broker.url, 'agv1', LinkSecurity(
        ca_file=good.ca_file, username=USER, password=PASSWORD)))
    assert message.startswith(f'MQTT broker {broker.url} refused client ')
    assert 'TLS: ' in message and 'certificate required' in message, message


def test_a_client_certificate_from_another_ca_is_refused(broker, links, good, tmp_path):
    """A certificate the broker's CA did not sign: mosquitto refuses it during the handshake."""
    stranger = TestCa(tmp_path / 'stranger', 'stranger CA').issue('agv1', server=False)
    message = _refusal(lambda: links(broker.url, 'agv1', LinkSecurity(
        ca_file=good.ca_file, cert_file=str(stranger.cert), key_file=str(stranger.key),
        username=USER, password=PASSWORD)))
    assert 'TLS: ' in message, message


@pytest.mark.parametrize(('username', 'password'), [(USER, 'wrong'), ('', ''), (USER, ''),
                                                    ('intruder', PASSWORD)],
                         ids=['bad password', 'no credentials', 'no password', 'unknown user'])
def test_bad_credentials_are_refused(broker, links, good, username, password):
    """Mosquitto answers CONNECT with "not authorised"; connect() says so in one line."""
    link = links(broker.url, 'agv1', LinkSecurity(
        ca_file=good.ca_file, cert_file=good.cert_file, key_file=good.key_file,
        username=username, password=password))
    message = _refusal(lambda: link)
    assert message == f"MQTT broker {broker.url} refused client 'agv1': Not authorized"
    assert link.stats().last_failure == 'Not authorized'  # what /diagnostics shows


def test_the_password_reaches_no_log_line_and_no_repr(broker, links, good, caplog):
    """Refused or accepted, the password appears in no log record and not in repr()."""
    caplog.set_level(logging.DEBUG)
    _refusal(lambda: links(broker.url, 'agv1', LinkSecurity(
        ca_file=good.ca_file, cert_file=good.cert_file, key_file=good.key_file,
        username=USER, password='wrong-' + PASSWORD)))
    links(broker.url, 'agv1_ok', good).connect(timeout=WAIT_S)
    assert PASSWORD not in caplog.text and PASSWORD not in repr(good)
    assert PASSWORD not in broker.log_path.read_text()


def test_plain_mqtt_to_a_tls_listener_does_not_connect(broker, links):
    """mqtt:// to the TLS port: no MQTT session (mosquitto drops the plain CONNECT)."""
    url = broker.url.replace('mqtts://', 'mqtt://')
    link = links(url, 'agv1', LinkSecurity(username=USER, password=PASSWORD))
    with pytest.raises((TimeoutError, ConnectionError)) as raised:
        link.connect(timeout=1.0)
    assert url in str(raised.value)


def test_tls_files_with_a_plain_url_are_refused_not_ignored(good):
    """Certificates named for mqtt:// would silently be unused: refused at construction."""
    with pytest.raises(ValueError, match='use an mqtts:// URL'):
        MqttLink('mqtt://127.0.0.1:1883', 'agv1', security=good)


@pytest.mark.parametrize(('security', 'words'), [
    (LinkSecurity(ca_file='/nonexistent/ca.pem'), 'TLS files for'),
    (LinkSecurity(cert_file='/x.crt'), 'give both or neither'),
    (LinkSecurity(password='p'), 'a password without a user name'),
])
def test_incomplete_security_is_one_clear_error(security, words):
    """A missing CA file, a certificate without key, a password without user: ValueError."""
    with pytest.raises(ValueError, match=words) as raised:
        MqttLink('mqtts://127.0.0.1:8883', 'agv1', security=security)
    assert '\n' not in str(raised.value)


def test_password_from_a_file_else_the_environment(tmp_path, monkeypatch):
    """The first line of the file wins; without a file AGV_MQTT_PASSWORD; bad files named."""
    monkeypatch.setenv(ENV_PASSWORD, 'from-env')
    secret = tmp_path / 'password'
    secret.write_text('from-file\nignored\n')
    assert read_password(str(secret)) == 'from-file'
    assert read_password('') == 'from-env'
    monkeypatch.delenv(ENV_PASSWORD)
    assert read_password('') == ''
    (tmp_path / 'empty').write_text('\n')
    with pytest.raises(ValueError, match='first line is empty'):
        read_password(str(tmp_path / 'empty'))
    with pytest.raises(ValueError, match=f'password file {tmp_path}/missing: cannot read'):
        read_password(str(tmp_path / 'missing'))


def test_anonymous_broker_without_tls_still_serves_plain_links(links):
    """The launcher's default: mosquitto, anonymous, mqtt://; a plain link connects."""
    require_mosquitto()
    with Mosquitto() as plain:
        assert plain.url.startswith('mqtt://127.0.0.1:')
        links(plain.url, 'agv1', LinkSecurity()).connect(timeout=WAIT_S)
