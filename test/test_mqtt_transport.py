"""The MQTT transport of the fleet interface: the embedded broker, MqttLink and broker_url.

Everything runs against a real broker on 127.0.0.1: the embedded amqtt (in a thread, or as a
process), the fallback these tests are about, and mosquitto (test/mqtt_broker.py). Every wait
is bounded and on an event or a queue, except the short ones checking that something does NOT
arrive.
"""

from collections.abc import Callable, Iterator
import queue
import re
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time

import mqtt_broker
import pytest

from agv_nodes.mqtt.broker import ENV_URL, EmbeddedBroker, broker_url
from agv_nodes.mqtt.client import LastWill, MqttLink, parse_mqtt_url

pytestmark = [pytest.mark.wall_clock, pytest.mark.timeout(60)]
mosquitto_url = mqtt_broker.mosquitto_url  # a private mosquitto for this module

WAIT_S = 10.0  # an upper bound only: on a loaded 2-core machine, messages take milliseconds
QUIET_S = 0.3  # how long a message that must not come is waited for
URL_RE = re.compile(r'mqtt://127\.0\.0\.1:(\d+)')


class Inbox:
    """A message callback that queues (topic, payload) for the test thread."""

    def __init__(self) -> None:
        self.messages: queue.Queue[tuple[str, bytes]] = queue.Queue()

    def __call__(self, topic: str, payload: bytes) -> None:
        self.messages.put((topic, payload))

    def next(self, timeout: float = WAIT_S) -> tuple[str, bytes]:
        try:
            return self.messages.get(timeout=timeout)
        except queue.Empty:
            raise AssertionError(f'no message within {timeout} s') from None

    def nothing(self, timeout: float = QUIET_S) -> None:
        try:
            message = self.messages.get(timeout=timeout)
        except queue.Empty:
            return
        raise AssertionError(f'unexpected message {message}')


@pytest.fixture
def broker() -> Iterator[EmbeddedBroker]:
    with EmbeddedBroker() as running:
        yield running


@pytest.fixture
def links() -> Iterator[Callable[..., MqttLink]]:
    """Make connected links; all are closed at the end of the test."""
    made: list[MqttLink] = []

    def make(url: str, client_id: str, connect: bool = True, **options: object) -> MqttLink:
        link = MqttLink(url, client_id, **options)
        made.append(link)
        if connect:
            link.connect(timeout=WAIT_S)
        return link

    yield make
    for link in made:
        link.close()


def _read_line(process: subprocess.Popen, timeout: float = WAIT_S) -> str:
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        if not selector.select(timeout):
            raise AssertionError(f'no line from {process.args} within {timeout} s')
    return process.stdout.readline()


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


# --- checks shared by the embedded broker and mosquitto ----------------------------------------

def _exchange(url: str, links: Callable[..., MqttLink], **options: object) -> None:
    """Two links exchange QoS 0 and QoS 1 messages both ways."""
    truck, master = links(url, 'truck_1', **options), links(url, 'master', **options)
    at_truck, at_master = Inbox(), Inbox()
    assert truck.subscribe('uagv/v2/maker/1/order', 1, at_truck)
    assert master.subscribe('uagv/v2/maker/+/state', 0, at_master)

    assert truck.publish('uagv/v2/maker/1/state', b'{"q": 0}', qos=0)
    assert at_master.next() == ('uagv/v2/maker/1/state', b'{"q": 0}')
    assert master.publish('uagv/v2/maker/1/order', '{"q": 1}', qos=1)
    assert at_truck.next() == ('uagv/v2/maker/1/order', b'{"q": 1}')

    truck_stats, master_stats = truck.stats(), master.stats()
    assert truck_stats.connected and truck_stats.connects == 1 and truck_stats.reconnects == 0
    assert (truck_stats.messages_out, truck_stats.messages_in) == (1, 1)
    assert (master_stats.messages_out, master_stats.messages_in) == (1, 1)
    assert truck_stats.as_dict()['messages_dropped'] == 0


_VICTIM = """
import sys, time
from agv_nodes.mqtt.client import LastWill, MqttLink, parse_mqtt_url
link = MqttLink(sys.argv[1], 'victim', will=LastWill('agv/victim/connection', b'BROKEN'))
link.connect()
link.publish('agv/victim/connection', b'ONLINE', qos=1)
time.sleep(60)
"""


def _last_will(url: str, links: Callable[..., MqttLink]) -> None:
    """Check that a killed process and a dropped socket bring out their wills, close() not."""
    watcher, wills = links(url, 'watcher'), Inbox()
    assert watcher.subscribe('agv/+/connection', 1, wills)

    victim = subprocess.Popen([sys.executable, '-c', _VICTIM, url])
    try:
        assert wills.next() == ('agv/victim/connection', b'ONLINE')
        victim.send_signal(signal.SIGKILL)
        assert wills.next() == ('agv/victim/connection', b'BROKEN')
    finally:
        victim.kill()
        victim.wait(WAIT_S)

    dropped = links(url, 'dropped', will=LastWill('agv/dropped/connection', 'BROKEN', qos=1))
    dropped.close(clean=False)
    assert wills.next() == ('agv/dropped/connection', b'BROKEN')

    polite = links(url, 'polite', will=LastWill('agv/polite/connection', b'BROKEN'))
    polite.close()
    # sent after the close: a will the close had caused would come before it or just after
    assert watcher.publish('agv/marker/connection', b'after', qos=1)
    assert wills.next() == ('agv/marker/connection', b'after')
    wills.nothing()


# --- the embedded broker -----------------------------------------------------------------------

def test_embedded_broker_serves_qos0_and_qos1(broker, links):
    """A broker on a free port; two links exchange messages at QoS 0 and 1."""
    match = URL_RE.fullmatch(broker.url)
    assert match and int(match.group(1)) == broker.port > 0
    _exchange(broker.url, links)


def test_two_brokers_at_once_get_different_ports(broker, links):
    """Each embedded broker picks its own free port and serves there."""
    with EmbeddedBroker() as second:
        assert second.port != broker.port
        assert links(second.url, 'truck_1').connected
        assert links(broker.url, 'truck_1').connected


def test_a_busy_port_is_a_clear_error(broker):
    """Asking for a port in use fails at start() with the port in the message."""
    with pytest.raises(RuntimeError, match=f'127.0.0.1:{broker.port}'):
        EmbeddedBroker(port=broker.port).start()


def test_retained_message_reaches_a_late_subscriber_and_an_empty_one_clears_it(broker, links):
    """Retain stores the last message for later subscribers; an empty retained one clears it."""
    topic = 'uagv/v2/maker/1/connection'
    publisher, echo = links(broker.url, 'publisher'), Inbox()
    assert publisher.subscribe(topic, 1, echo)
    assert publisher.publish(topic, b'ONLINE', qos=1, retain=True)
    assert echo.next() == (topic, b'ONLINE')  # the broker has it (and has stored it)

    late, at_late = links(broker.url, 'late'), Inbox()
    assert late.subscribe(topic, 1, at_late)
    assert at_late.next() == (topic, b'ONLINE')

    assert publisher.publish(topic, b'', qos=1, retain=True)
    assert echo.next() == (topic, b'')
    assert publisher.publish('uagv/v2/maker/1/marker', b'm', qos=1, retain=True)
    later, at_later = links(broker.url, 'later'), Inbox()
    assert later.subscribe(topic, 1, at_later)
    # a retained message for the first filter would come before the second filter's
    assert later.subscribe('uagv/v2/maker/1/marker', 1, at_later)
    assert at_later.next() == ('uagv/v2/maker/1/marker', b'm')
    at_later.nothing()


def test_last_will_on_a_lost_connection_not_on_a_clean_close(broker, links):
    """SIGKILL and a dropped socket publish the will; close() does not."""
    _last_will(broker.url, links)


def test_link_reconnects_to_a_restarted_broker(links):
    """Broker gone and back on the same port: the link returns, subscriptions and all."""
    first = EmbeddedBroker()
    url = first.start()
    try:
        truck = links(url, 'truck_1', connect=False, reconnect_min_s=0.05, reconnect_max_s=0.2)
        states: queue.Queue[bool] = queue.Queue()
        truck.on_connection(states.put)
        orders = Inbox()
        assert not truck.subscribe('agv/order', 1, orders)  # not connected: made at connect
        assert not truck.subscribe('agv/echo', 1, orders)
        truck.connect(timeout=WAIT_S)
        assert states.get(timeout=WAIT_S) is True
    finally:
        first.stop()
    assert states.get(timeout=WAIT_S) is False
    assert not truck.connected
    assert not truck.publish('agv/echo', b'lost', qos=0)  # QoS 0 while down: dropped
    assert truck.publish('agv/echo', b'kept', qos=1)  # QoS 1: sent after the reconnect

    with EmbeddedBroker(port=int(URL_RE.fullmatch(url).group(1))) as second:
        assert second.url == url
        assert states.get(timeout=WAIT_S) is True
        assert orders.next() == ('agv/echo', b'kept')
        master = links(url, 'master', reconnect_min_s=0.05)
        assert master.publish('agv/order', b'again', qos=1)
        assert orders.next() == ('agv/order', b'again')
        stats = truck.stats()
        assert stats.connected and stats.connects == 2 and stats.reconnects == 1
        assert stats.messages_dropped == 1
        assert 0 < stats.last_gap_s < WAIT_S
        assert abs(time.time() - stats.last_disconnect) < 60
        truck.close()
        assert states.get(timeout=WAIT_S) is False


def test_broker_stops_promptly_under_traffic(links):
    """stop() returns quickly while clients publish and acknowledge QoS 1 messages."""
    broker = EmbeddedBroker(stop_timeout_s=WAIT_S)
    url = broker.start()
    try:
        busy, received = links(url, 'busy', reconnect_min_s=0.05), Inbox()
        assert busy.subscribe('agv/load', 1, received)
        running = threading.Event()
        running.set()

        def publish_all_the_time() -> None:
            while running.is_set():
                busy.publish('agv/load', b'x' * 100, qos=1)
                time.sleep(0.001)

        publisher = threading.Thread(target=publish_all_the_time, daemon=True)
        publisher.start()
        received.next()
        started = time.monotonic()
        broker.stop()
        assert time.monotonic() - started < 5.0
    finally:
        running.clear()
        publisher.join(WAIT_S)
        broker.stop()


def test_a_failing_callback_does_not_stop_the_link(broker, links):
    """A message callback that raises is logged; the next message still arrives."""
    link, inbox = links(broker.url, 'truck_1'), Inbox()

    def broken(topic: str, payload: bytes) -> None:
        raise RuntimeError('bridge bug')

    assert link.subscribe('agv/bad', 0, broken)
    assert link.subscribe('agv/good', 0, inbox)
    assert link.publish('agv/bad', b'1', qos=1)
    assert link.publish('agv/good', b'2', qos=1)
    assert inbox.next() == ('agv/good', b'2')


def test_connect_to_no_broker_times_out_naming_it():
    """connect() to a port nobody listens on gives up after its timeout, naming the URL."""
    url = f'mqtt://127.0.0.1:{_free_port()}'
    link = MqttLink(url, 'truck_1', reconnect_min_s=0.05, reconnect_max_s=0.1)
    with pytest.raises(TimeoutError, match=re.escape(url)):
        link.connect(timeout=0.5)
    assert link.stats().failed_attempts >= 1


@pytest.mark.parametrize('stop_signal', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
@pytest.mark.parametrize('which', [[], ['--embedded']], ids=['mosquitto', 'embedded'])
def test_broker_runs_as_a_process(tmp_path, links, stop_signal, which):
    """`python -m agv_nodes.mqtt.broker` prints one URL line, serves, exits 0 on a signal.

    Without --embedded it runs mosquitto (installed here, as on CI).
    """
    if not which:
        mqtt_broker.require_mosquitto()
    process = subprocess.Popen([sys.executable, '-m', 'agv_nodes.mqtt.broker', *which],
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        line = _read_line(process)
        assert URL_RE.fullmatch(line.rstrip('\n')), line
        url = line.strip()
        # the links stay connected: the broker must also stop with clients on it
        _exchange(url, links, reconnect_min_s=0.05, reconnect_max_s=0.1)
        process.send_signal(stop_signal)
        out, err = process.communicate(timeout=WAIT_S)
    finally:
        process.kill()
        process.wait(WAIT_S)
    assert process.returncode == 0, err
    assert out == '' and err == ''  # the URL line was the only one
    assert list(tmp_path.iterdir()) == []  # nothing written where it ran
    assert _refuses(url)  # mosquitto, a process of its own, ended with it


def _refuses(url: str) -> bool:
    host, port = parse_mqtt_url(url)
    try:
        socket.create_connection((host, port), timeout=1.0).close()
    except OSError:
        return True
    return False


@pytest.mark.parametrize('which', [[], ['--embedded']], ids=['mosquitto', 'embedded'])
def test_broker_process_on_a_busy_port_exits_1(broker, which):
    """--port with a port in use: exit status 1 and the port on stderr, in one line."""
    run = subprocess.run([sys.executable, '-m', 'agv_nodes.mqtt.broker', '--port',
                          str(broker.port), *which], capture_output=True, text=True,
                         timeout=WAIT_S * 3)
    assert run.returncode == 1 and run.stdout == ''
    assert f'127.0.0.1:{broker.port}' in run.stderr and run.stderr.count('\n') == 1, run.stderr


# --- choosing the broker -----------------------------------------------------------------------

def test_broker_url_explicit_beats_environment_beats_none(monkeypatch):
    """--mqtt-url wins over AGV_MQTT_URL; neither (or an empty variable) means embedded."""
    monkeypatch.delenv(ENV_URL, raising=False)
    assert broker_url(None) is None
    monkeypatch.setenv(ENV_URL, '')
    assert broker_url(None) is None
    monkeypatch.setenv(ENV_URL, 'mqtt://broker.local')
    assert broker_url(None) == 'mqtt://broker.local:1883'
    assert broker_url('mqtt://127.0.0.1:1884') == 'mqtt://127.0.0.1:1884'
    assert broker_url('mqtt://[::1]:1885') == 'mqtt://[::1]:1885'
    assert broker_url('mqtts://broker.plant') == 'mqtts://broker.plant:8883'
    assert broker_url('MQTTS://127.0.0.1:18883') == 'mqtts://127.0.0.1:18883'


BAD_URLS = [
    ('', 'empty'),
    ('localhost:1883', 'not an mqtt:// URL'),
    ('http://localhost:1883', 'not an mqtt:// URL'),
    ('wss://localhost:8883', 'not supported'),
    ('mqtt://localhost:99999', 'not a number 1-65535'),
    ('mqtt://localhost:port', 'not a number 1-65535'),
    ('mqtt://localhost:0', 'port 0'),
    ('mqtt://:1883', 'no host'),
    ('mqtt://localhost:1883/agv', 'path'),
    ('mqtt://user:secret@localhost', 'password in the URL is refused'),
    ('mqtts://user@localhost', 'user name or password in the URL'),
    (' mqtt://localhost', 'blanks'),
]


@pytest.mark.parametrize(('source', 'value', 'problem'),
                         [('--mqtt-url', *case) for case in BAD_URLS]
                         + [(ENV_URL, *case) for case in BAD_URLS if case[0]])
def test_broker_url_rejects_bad_urls_in_one_line(monkeypatch, source, value, problem):
    """A bad URL: ValueError naming the source, the value and the problem, on one line."""
    if source == ENV_URL:
        monkeypatch.setenv(ENV_URL, value)
        explicit = None
    else:
        monkeypatch.setenv(ENV_URL, 'mqtt://ignored')
        explicit = value
    with pytest.raises(ValueError) as raised:
        broker_url(explicit)
    message = str(raised.value)
    assert message.startswith(f'{source} {value!r}: ') and '\n' not in message
    assert problem in message, message


# --- a real broker -----------------------------------------------------------------------------

def test_against_mosquitto(mosquitto_url, links, monkeypatch):
    """The exchange and the last will against mosquitto, chosen through an explicit URL."""
    monkeypatch.setenv(ENV_URL, 'mqtt://127.0.0.1:1')
    url = broker_url(mosquitto_url)
    _exchange(url, links)
    _last_will(url, links)


def test_local_broker_is_mosquitto_where_installed_else_amqtt_saying_why(monkeypatch):
    """The launcher's choice: mosquitto when found; amqtt otherwise, its name saying why."""
    import agv_nodes.mqtt.broker as broker_module
    from agv_nodes.mqtt.mosquitto import Mosquitto

    mqtt_broker.require_mosquitto()
    assert isinstance(broker_module.local_broker(), Mosquitto)
    embedded = broker_module.local_broker(embedded=True)
    assert isinstance(embedded, EmbeddedBroker) and embedded.name == 'embedded amqtt'
    monkeypatch.setattr(broker_module, 'find_mosquitto', lambda: None)
    fallback = broker_module.local_broker()
    assert isinstance(fallback, EmbeddedBroker)
    assert fallback.name == 'embedded amqtt: mosquitto is not installed'
