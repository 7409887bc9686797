"""One truck's MQTT connection: paho-mqtt 2.x with a last will, reconnection and counters.

A VDA 5050 bridge needs three things paho leaves to its user: subscriptions that survive a
reconnect (paho forgets them; the broker forgets them too under a clean session), a report of
each gap in the connection (the master must see the truck go quiet, and the bridge must know
when its subscriptions are live again), and numbers for diagnostics. `MqttLink` adds those and
nothing else: MQTT 3.1.1, a clean session; TLS when the URL is mqtts:// (`LinkSecurity`: the CA
that signed the broker's certificate, optionally the client's certificate and key) and a user
name with a password when given. Credentials never go into the URL (it is printed in logs).

Threads: paho runs the network in its own thread (`loop_start`); every callback given to
`MqttLink` (message callbacks, `on_connection`) runs on that thread, one at a time, and must not
block. The link's own state is guarded by one lock, never held while a user callback runs, so
callbacks may call back into the link (publish, subscribe, stats). A callback that raises is
logged and the network thread carries on (paho would otherwise let it end the thread).
"""

from collections.abc import Callable
from dataclasses import asdict, dataclass
import logging
import socket
import ssl
import sys
import threading
import time
from typing import Any

from paho.mqtt.client import MQTT_LOG_ERR, Client, MQTTv311, topic_matches_sub
from paho.mqtt.enums import CallbackAPIVersion, MQTTErrorCode

from agv_nodes.mqtt.address import LinkSecurity, parse_mqtt_url, uses_tls
from agv_nodes.mqtt.failure import READ_FAILED, failure_text, log_failure_text

_log = logging.getLogger(__name__)

MessageCallback = Callable[[str, bytes], None]
ConnectionCallback = Callable[[bool], None]


@dataclass(frozen=True)
class LastWill:
    """What the broker publishes for this client when its connection is lost without DISCONNECT.

    VDA 5050's connection topic uses qos 1 and retain, so the master sees CONNECTIONBROKEN even
    when it subscribes later.
    """

    topic: str
    payload: bytes | str
    qos: int = 1
    retain: bool = False


@dataclass(frozen=True)
class LinkStats:
    """A snapshot of one link's counters, for diagnostics.

    `connected` is True once the broker accepted the connection and the subscriptions were
    re-made. `messages_dropped` counts QoS 0 publishes refused while disconnected (QoS 1 ones
    are queued by paho and sent after the reconnect). `last_disconnect` is wall-clock time
    (time.time()); `last_gap_s` is how long the last outage lasted, None before the first one
    ended; `last_failure` the broker's refusal or the last failed attempt's reason (None once
    connected), so /diagnostics says why a truck is off the broker.
    """

    connected: bool
    messages_in: int
    messages_out: int
    messages_dropped: int
    connects: int
    reconnects: int
    failed_attempts: int
    last_disconnect: float | None
    last_gap_s: float | None
    last_failure: str | None = None  # why the broker refused the link or could not be reached

    def as_dict(self) -> dict[str, Any]:
        """Return the counters as a plain dict (for a diagnostics message or a log line)."""
        return asdict(self)


@dataclass
class _Subscription:
    qos: int
    callback: MessageCallback


class MqttLink:
    """One MQTT 3.1.1 connection with a last will, automatic reconnection and counters.

    `connect()` starts paho's network thread; from then on a lost connection is retried with
    an exponential back-off from `reconnect_min_s` to `reconnect_max_s`, the subscriptions are
    re-made, and `on_connection` callbacks hear False at the loss and True when the link is
    usable again. `close()` sends DISCONNECT, so the broker drops the will;
    `close(clean=False)` drops the socket, so the broker publishes it. A connection that dies
    without a FIN (cable, power) is noticed by the broker after 1.5 keepalive_s, and the will
    goes out then.
    """

    def __init__(self, url: str, client_id: str, will: LastWill | None = None,
                 reconnect_min_s: float = 1.0, reconnect_max_s: float = 30.0,
                 keepalive_s: int = 30, security: LinkSecurity | None = None) -> None:
        self.url = url
        self.client_id = client_id
        self._host, self._port = parse_mqtt_url(url)
        security = security or LinkSecurity()
        self._tls = tls = uses_tls(url)
        if security.tls_files and not tls:
            raise ValueError(f'TLS files given for {url}: use an mqtts:// URL, or name none')
        if bool(security.cert_file) != bool(security.key_file):
            raise ValueError('a client certificate needs its key and a key its certificate: '
                             'give both or neither')
        if security.password and not security.username:
            raise ValueError('a password without a user name')
        if not 0 < reconnect_min_s <= reconnect_max_s:
            raise ValueError(f'reconnect back-off: need 0 < min ({reconnect_min_s}) <= max '
                             f'({reconnect_max_s})')
        self._keepalive_s = keepalive_s
        self._lock = threading.Condition()
        self._subscriptions: dict[str, _Subscription] = {}
        self._connection_callbacks: list[ConnectionCallback] = []
        self._session_up = False  # CONNACK accepted; subscribe() may send at once
        self._ready = False  # and the subscriptions are re-made: what on_connection reports
        self._restore_mid: int | None = None
        self._sent: dict[int, bool | None] = {}  # SUBSCRIBE mid -> granted (None: no SUBACK yet)
        self._refusal: str | None = None
        self._last_failure: str | None = None  # why the last connection attempt failed
        self._first_ready = threading.Event()
        self._network_thread: int | None = None
        self._down_since: float | None = None
        self._counts = dict(messages_in=0, messages_out=0, messages_dropped=0, connects=0,
                            reconnects=0, failed_attempts=0)
        self._last_disconnect: float | None = None
        self._last_gap_s: float | None = None

        self._client = Client(callback_api_version=CallbackAPIVersion.VERSION2,
                              client_id=client_id, clean_session=True, protocol=MQTTv311)
        # paho types these as int; fractions of a second work (they feed time.sleep)
        self._client.reconnect_delay_set(reconnect_min_s, reconnect_max_s)
        if tls:
            try:
                self._client.tls_set(ca_certs=security.ca_file or None,
                                     certfile=security.cert_file or None,
                                     keyfile=security.key_file or None)
            except (OSError, ssl.SSLError) as exc:  # a file missing or not PEM
                raise ValueError(f'TLS files for {url}: {exc}') from None
        if security.username:
            self._client.username_pw_set(security.username, security.password or None)
        if will is not None:
            self._client.will_set(will.topic, will.payload, will.qos, will.retain)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_connect_fail = self._on_connect_fail
        self._client.on_log = self._on_log
        self._client.on_subscribe = self._on_subscribe
        self._client.on_message = self._on_message

    # --- the caller's side -----------------------------------------------------------------

    def on_connection(self, callback: ConnectionCallback) -> None:
        """Call callback(True) each time the link becomes usable, callback(False) at each loss."""
        with self._lock:
            self._connection_callbacks.append(callback)

    def connect(self, timeout: float | None = 10.0) -> None:
        """Start the network thread and wait (at most timeout s) until the link is usable.

        With timeout None, return at once: the link keeps trying in the background and reports
        through `on_connection`. On a refusal or a timeout the network thread is stopped and
        ConnectionError / TimeoutError names the broker.
        """
        self._client.connect_async(self._host, self._port, keepalive=self._keepalive_s)
        self._client.loop_start()
        if timeout is None:
            return
        if not self._first_ready.wait(timeout):
            self._stop_network()
            with self._lock:
                why = self._last_failure or 'is it running?'
            raise TimeoutError(f'MQTT broker {self.url} did not accept client '
                               f'{self.client_id!r} within {timeout:g} s ({why})')
        with self._lock:
            refusal = self._refusal
        if refusal is not None:
            self._stop_network()
            raise ConnectionError(f'MQTT broker {self.url} refused client {self.client_id!r}: '
                                  f'{refusal}')

    def publish(self, topic: str, payload: bytes | str, qos: int = 0,
                retain: bool = False) -> bool:
        """Publish; return False when a QoS 0 message had to be dropped (not connected).

        QoS 1 messages published while disconnected are kept by paho and sent after the
        reconnect. An empty retained payload clears the broker's retained message on the topic.
        """
        info = self._client.publish(topic, payload, qos, retain)
        sent = info.rc == MQTTErrorCode.MQTT_ERR_SUCCESS or (
            qos > 0 and info.rc == MQTTErrorCode.MQTT_ERR_NO_CONN)
        with self._lock:
            self._counts['messages_out' if sent else 'messages_dropped'] += 1
        return sent

    def subscribe(self, topic_filter: str, qos: int, callback: MessageCallback,
                  timeout: float = 5.0) -> bool:
        """Subscribe callback(topic, payload) to a topic filter, also after every reconnect.

        Returns True once the broker granted it (SUBACK, waited for at most timeout s; not
        waited for when called on the network thread). False means not granted yet: not
        connected (it is made at the next connect), refused, or no SUBACK in time. A second
        subscribe to the same filter replaces the first.
        """
        with self._lock:
            self._subscriptions[topic_filter] = _Subscription(qos, callback)
            if not self._session_up:
                return False
            # sent under the lock so the SUBACK cannot be handled before its mid is recorded
            result, mid = self._client.subscribe(topic_filter, qos)
            if result != MQTTErrorCode.MQTT_ERR_SUCCESS or mid is None:
                return False
            if threading.get_ident() == self._network_thread:
                return True  # its SUBACK can only come after this callback returns
            self._sent[mid] = None
            self._lock.wait_for(lambda: self._sent[mid] is not None or not self._session_up,
                                timeout)
            return bool(self._sent.pop(mid))

    def stats(self) -> LinkStats:
        """Return a consistent snapshot of the counters."""
        with self._lock:
            return LinkStats(connected=self._ready, last_disconnect=self._last_disconnect,
                             last_gap_s=self._last_gap_s,
                             last_failure=self._refusal or self._last_failure, **self._counts)

    @property
    def connected(self) -> bool:
        """True while the link is usable (connected, subscriptions re-made)."""
        with self._lock:
            return self._ready

    def close(self, clean: bool = True) -> None:
        """End the link and its network thread.

        clean: send DISCONNECT, so the broker discards the will. clean=False drops the TCP
        connection without it, as a crash would, so the broker publishes the will. While the
        link waits to reconnect this takes up to a second (paho checks every second).
        """
        if not clean:
            sock = self._client.socket()
            if isinstance(sock, socket.socket):
                # the FIN goes out before any DISCONNECT could: the broker sees a lost client
                try:
                    sock.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
        self._stop_network()

    def __enter__(self) -> 'MqttLink':
        self.connect()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _stop_network(self) -> None:
        # disconnect() also ends a back-off wait; loop_stop() then returns within about a second
        self._client.disconnect()
        self._client.loop_stop()

    # --- paho's network thread -------------------------------------------------------------

    def _on_connect(self, client: Client, userdata: Any, flags: Any, reason_code: Any,
                    properties: Any) -> None:
        if reason_code.is_failure:
            with self._lock:
                self._refusal = str(reason_code)
                self._counts['failed_attempts'] += 1
            _log.warning('MQTT broker %s refused client %r: %s', self.url, self.client_id,
                         reason_code)
            self._first_ready.set()
            return
        with self._lock:
            self._network_thread = threading.get_ident()
            self._refusal = self._last_failure = None
            self._session_up = True
            wanted = [(topic, s.qos) for topic, s in self._subscriptions.items()]
            self._restore_mid = None
            if wanted:
                result, mid = client.subscribe(wanted)
                if result == MQTTErrorCode.MQTT_ERR_SUCCESS:
                    self._restore_mid = mid
                    return  # usable once the SUBACK is in (_on_subscribe)
        self._become_ready()

    def _on_subscribe(self, client: Client, userdata: Any, mid: int, reason_codes: Any,
                      properties: Any) -> None:
        granted = not any(code.is_failure for code in reason_codes)
        if not granted:
            _log.warning('MQTT broker %s refused a subscription of client %r: %s', self.url,
                         self.client_id, [str(code) for code in reason_codes])
        with self._lock:
            restored = mid == self._restore_mid
            if mid in self._sent:
                self._sent[mid] = granted
                self._lock.notify_all()
        if restored:
            self._become_ready()

    def _become_ready(self) -> None:
        with self._lock:
            self._ready = True
            self._counts['connects'] += 1
            gap_s = None
            if self._down_since is not None:
                self._counts['reconnects'] += 1
                gap_s = self._last_gap_s = time.monotonic() - self._down_since
                self._down_since = None
            callbacks = list(self._connection_callbacks)
        if gap_s is not None:
            _log.info('MQTT client %r back on %s after %.1f s', self.client_id, self.url, gap_s)
        # the listeners first: connect(timeout) returns once they know (a truck's face then
        # says ONLINE and its factsheet before its first state)
        self._report(callbacks, True)
        self._first_ready.set()

    def _on_disconnect(self, client: Client, userdata: Any, flags: Any, reason_code: Any,
                       properties: Any) -> None:
        with self._lock:
            was_ready = self._ready
            # a TLS connection the broker ends before its CONNACK is its TLS refusal (a client
            # certificate it requires and did not get, or does not trust)
            refused = (not self._session_up and not self._ready and self._tls
                       and self._last_failure is not None
                       and self._last_failure.startswith('TLS'))
            if refused:
                self._refusal = self._last_failure
            self._session_up = self._ready = False
            self._restore_mid = None
            self._lock.notify_all()  # a subscribe() waiting for its SUBACK gives up
            if was_ready:
                self._down_since = time.monotonic()
                self._last_disconnect = time.time()
            callbacks = list(self._connection_callbacks)
        if was_ready:
            _log.info('MQTT client %r lost %s: %s', self.client_id, self.url, reason_code)
            self._report(callbacks, False)
        if refused:
            self._first_ready.set()

    def _on_log(self, client: Client, userdata: Any, level: int, text: str) -> None:
        # paho reports a failed read (a TLS alert from the broker among them) only in its log
        if level != MQTT_LOG_ERR or not text.startswith(READ_FAILED):
            return
        why = log_failure_text(text)
        with self._lock:
            if self._session_up:
                return
            new = why != self._last_failure
            self._last_failure = why
        if new:
            _log.warning('MQTT broker %s: client %r cannot connect: %s', self.url,
                         self.client_id, why)

    def _on_connect_fail(self, client: Client, userdata: Any) -> None:
        # paho calls this inside its `except OSError`, so the exception is still at hand
        error = sys.exc_info()[1]
        why = failure_text(error) if error is not None else 'connection failed'
        with self._lock:
            self._counts['failed_attempts'] += 1
            new = why != self._last_failure
            self._last_failure = why
            # a TLS refusal (wrong CA, no client certificate) fails the same way each time:
            # connect() need not wait out its timeout to say so
            permanent = isinstance(error, ssl.SSLError) and not self._ready
            if permanent:
                self._refusal = why
        if new:
            _log.warning('MQTT broker %s: client %r cannot connect: %s', self.url,
                         self.client_id, why)
        if permanent:
            self._first_ready.set()

    def _on_message(self, client: Client, userdata: Any, message: Any) -> None:
        topic = message.topic
        with self._lock:
            self._counts['messages_in'] += 1
            callbacks = [s.callback for topic_filter, s in self._subscriptions.items()
                         if topic_matches_sub(topic_filter, topic)]
        for callback in callbacks:
            try:
                callback(topic, message.payload)
            except Exception:
                _log.exception('MQTT message callback failed on %r', topic)

    def _report(self, callbacks: list[ConnectionCallback], connected: bool) -> None:
        for callback in callbacks:
            try:
                callback(connected)
            except Exception:
                _log.exception('MQTT on_connection callback failed')

