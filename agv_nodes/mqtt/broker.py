"""The broker the launcher starts when none is given: mosquitto, else the embedded amqtt.

A VDA 5050 master and the trucks' bridges meet at an MQTT broker. With `--mqtt-url` or
AGV_MQTT_URL the launcher uses that one (`broker_url`); else it starts its own on 127.0.0.1, on
a free port, anonymous, with nothing written to disk (`local_broker`): mosquitto, what plants
run, wherever it is installed (agv_nodes.mqtt.mosquitto), and amqtt only where it is not.
`EmbeddedBroker` runs amqtt's asyncio broker in a thread of its own so that synchronous code
(the launcher, tests) can start and stop it; `python -m agv_nodes.mqtt.broker` runs the local
broker as a process of its own and prints its URL.

amqtt binds port 0 like any asyncio server but does not report the port it got, so it is read
from the listening socket in `Broker._servers` (a private attribute of amqtt 0.12; a changed
amqtt fails here with a clear message, not later with a wrong port). `_shutdown` closes that
listener and the client connections itself: amqtt's own shutdown could hang on Python 3.11
while clients were sending.

amqtt 0.12.1 sends retained messages wrongly: when a client connects it walks every topic filter
any client subscribes to and sends the new client the retained messages matching them, at QoS 0
(`Broker.client_connected`), and then again, at the granted QoS, when the client subscribes. A
new subscriber thus got other topics' retained messages and each of its own twice (what
test_mqtt_embedded.py shows on the unmodified broker). `_RetainFixBroker` sends retained
messages only while it handles that client's own SUBSCRIBE (MQTT 3.1.1, 3.3.1.3: retained
messages go to a new subscription), so each matching one goes once, at min(granted, stored) QoS.
"""

from __future__ import annotations

import argparse
import asyncio
from contextvars import ContextVar
import logging
import os
import signal
import sys
import threading
from typing import Any

from amqtt.broker import Broker

from agv_nodes.mqtt.address import ENV_URL, format_mqtt_url, parse_mqtt_url, uses_tls
from agv_nodes.mqtt.mosquitto import Mosquitto, find_mosquitto

HOST = '127.0.0.1'
_LISTENER = 'default'
_log = logging.getLogger(__name__)
# the session whose SUBSCRIBE the running asyncio task handles (each client has its own task)
_subscribing: ContextVar[object | None] = ContextVar('subscribing', default=None)
_PATCHED = ('_handle_subscription', '_publish_retained_messages_for_subscription')


class _RetainFixBroker(Broker):
    """amqtt's Broker sending retained messages only for the subscriber's own SUBSCRIBE."""

    async def _handle_subscription(self, client_session: Any, handler: Any,
                                   subscribe_waiter: Any) -> None:
        token = _subscribing.set(client_session)
        try:
            await super()._handle_subscription(client_session, handler, subscribe_waiter)
        finally:
            _subscribing.reset(token)

    async def _publish_retained_messages_for_subscription(self, subscription: tuple[str, int],
                                                          session: Any) -> None:
        if _subscribing.get() is not session:
            return  # the pass at CONNECT over every client's filters: nothing was subscribed
        await super()._publish_retained_messages_for_subscription(subscription, session)


def _check_amqtt() -> None:
    missing = [name for name in _PATCHED if not hasattr(Broker, name)]
    if missing:
        raise RuntimeError(f'amqtt has no Broker.{missing[0]} (changed with this amqtt '
                           'version): the retained-message fix in agv_nodes.mqtt.broker '
                           'needs updating')


def broker_url(explicit: str | None) -> str | None:
    """Return the URL of the broker to use, or None to start the embedded one.

    The explicit `--mqtt-url` value wins over the AGV_MQTT_URL environment variable (an empty
    variable counts as unset). The URL comes back canonical (mqtt[s]://host:port); a bad one raises
    ValueError in one line naming where it came from, the value and what is wrong.
    """
    if explicit is not None:
        source, value = '--mqtt-url', explicit
    elif os.environ.get(ENV_URL):
        source, value = ENV_URL, os.environ[ENV_URL]
    else:
        return None
    try:
        host, port = parse_mqtt_url(value)
    except ValueError as exc:
        raise ValueError(f'{source} {value!r}: {exc}') from None
    return format_mqtt_url(host, port, tls=uses_tls(value))


def local_broker(port: int = 0, host: str = HOST,
                 embedded: bool = False) -> Mosquitto | EmbeddedBroker:
    """Return a local broker to start: mosquitto when installed (and not `embedded`), else amqtt.

    Its `name` says which, and for amqtt why (what the launcher prints in one line).
    """
    if not embedded and find_mosquitto() is not None:
        return Mosquitto(host=host, port=port)
    broker = EmbeddedBroker(port=port, host=host)
    if not embedded:
        broker.name = 'embedded amqtt: mosquitto is not installed'
    return broker


def _broker_config(host: str, port: int) -> dict[str, Any]:
    # Plugins listed explicitly replace amqtt's defaults (a $SYS publisher, event and packet
    # loggers); no persistence plugin either (amqtt's writes amqtt.db into the cwd). Anonymous
    # clients must be allowed by a plugin: with none, amqtt refuses every CONNECT.
    return {
        'listeners': {_LISTENER: {'type': 'tcp', 'bind': f'{host}:{port}'}},
        'plugins': {'amqtt.plugins.authentication.AnonymousAuthPlugin':
                    {'allow_anonymous': True}},
    }


def _quiet_amqtt() -> None:
    # amqtt logs each connection at INFO and its state machine (transitions) each change; keep
    # warnings and errors unless the caller set these loggers' levels already
    for name in ('amqtt', 'transitions'):
        logger = logging.getLogger(name)
        if logger.level == logging.NOTSET:
            logger.setLevel(logging.WARNING)
    # a failed start (a port in use) comes back from start() as one line; amqtt's traceback of
    # it would bury that line
    broker_log = logging.getLogger('amqtt.broker')
    if _drop_startup_traceback not in broker_log.filters:
        broker_log.addFilter(_drop_startup_traceback)


def _drop_startup_traceback(record: logging.LogRecord) -> bool:
    return not str(record.msg).startswith('Broker startup failed')


class EmbeddedBroker:
    """amqtt on 127.0.0.1 (MQTT 3.1.1, anonymous) in a thread with its own asyncio loop.

    port 0 lets the system choose a free port; a given port (e.g. to restart a broker where a
    stopped one was) must be free. `start()` returns once the port listens; `stop()` closes
    every client connection and joins the thread. Usable as a context manager.
    """

    def __init__(self, port: int = 0, start_timeout_s: float = 10.0,
                 stop_timeout_s: float = 15.0, host: str = HOST,
                 fix_retained: bool = True) -> None:
        """Listen on `host` and `port` (0: a free one).

        `host` 127.0.0.1 serves this machine only; an interface's address serves a fleet whose
        trucks are on other hosts. fix_retained=False runs amqtt as it is (for the test that
        shows what the fix changes).
        """
        self.host = host
        self.fix_retained = fix_retained
        self.name = 'embedded amqtt'
        self._requested_port = port
        self._start_timeout_s = start_timeout_s
        self._stop_timeout_s = stop_timeout_s
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop_request: asyncio.Event | None = None
        self._ready = threading.Event()
        self._stopping = False
        self._error: BaseException | None = None
        self.port: int | None = None

    @property
    def url(self) -> str:
        """mqtt://HOST:PORT of the running broker."""
        if self.port is None:
            raise RuntimeError('the embedded MQTT broker is not running')
        return format_mqtt_url(self.host, self.port)

    def start(self) -> str:
        """Start amqtt, wait until its port listens and return its URL.

        amqtt's start returns after listen(), so connections are accepted from then on; a probe
        connection would prove nothing more (and amqtt logs one that sends no CONNECT as an
        error). RuntimeError names the port when amqtt cannot listen there or does not start
        within start_timeout_s.
        """
        if self._thread is not None:
            raise RuntimeError('the embedded MQTT broker is already started')
        _quiet_amqtt()
        self._ready.clear()
        self._stopping = False
        self._error = None
        where = f'{self.host}:{self._requested_port or "<any free port>"}'
        self._thread = threading.Thread(target=self._run, name='mqtt-broker', daemon=True)
        self._thread.start()
        if not self._ready.wait(self._start_timeout_s):
            try:
                self.stop()
            except RuntimeError:  # the error below says more
                pass
            raise RuntimeError(f'the embedded MQTT broker did not listen on {where} within '
                               f'{self._start_timeout_s:g} s')
        if self._error is not None:
            error = self._error
            self._thread.join(self._stop_timeout_s)
            self._thread = None
            raise RuntimeError(f'the embedded MQTT broker cannot listen on {where}: '
                               f'{error}') from error
        return self.url

    def stop(self) -> None:
        """Shut the broker down (clients see their connection closed) and join its thread."""
        thread = self._thread
        if thread is None:
            return
        # set before the loop is looked at: a broker still starting either sees the flag or
        # has its loop and stop request in place for the call below
        self._stopping = True
        loop = self._loop
        if loop is not None and self._stop_request is not None:
            try:
                loop.call_soon_threadsafe(self._stop_request.set)
            except RuntimeError:  # the loop has ended already
                pass
        thread.join(self._stop_timeout_s)
        if thread.is_alive():
            raise RuntimeError(f'the embedded MQTT broker on port {self.port} did not stop '
                               f'within {self._stop_timeout_s:g} s')
        self._thread = None
        self.port = None

    def __enter__(self) -> EmbeddedBroker:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
            # the connection handlers amqtt leaves behind end with their sockets; wait for them,
            # then cancel what is left, so that closing the loop destroys no pending task
            for cancel in (False, True):
                pending = asyncio.all_tasks(loop)
                for task in pending if cancel else ():
                    task.cancel()
                if pending:
                    loop.run_until_complete(asyncio.wait(pending, timeout=1.0))
            loop.run_until_complete(loop.shutdown_asyncgens())
        except BaseException as exc:  # reported to start(); the thread must not die silently
            self._error = exc
            _log.exception('the embedded MQTT broker failed')
        finally:
            self._loop = None
            loop.close()
            self._ready.set()

    async def _serve(self) -> None:
        self._stop_request = asyncio.Event()
        _check_amqtt()
        broker = (_RetainFixBroker if self.fix_retained else Broker)(
            _broker_config(self.host, self._requested_port), loop=asyncio.get_running_loop())
        try:
            await broker.start()
        except Exception as exc:  # amqtt wraps a bind error in BrokerError
            self._error = exc
            self._ready.set()
            return
        try:
            self.port = _bound_port(broker)
        except RuntimeError as exc:
            self._error = exc
        self._ready.set()
        if self._error is None and not self._stopping:
            await self._stop_request.wait()
        await _shutdown(broker, self._stop_timeout_s / 2)


async def _shutdown(broker: Broker, timeout_s: float) -> None:
    """broker.shutdown(), after closing the listener and then every client connection.

    amqtt's shutdown cancels each client's reader task and waits for it to end. On Python 3.11,
    asyncio.wait_for swallows a cancellation that arrives just as its read completes (fixed in
    3.12), and the reader goes on reading: a client that sent anything at that moment (a PUBACK,
    a PINGREQ) held the shutdown until its keep-alive ran out (seen: 30 s), and one publishing
    steadily held it for good. With its connection closed first, a reader stops at the end of
    the data already received, cancelled or not. The listener is closed before that, or a
    client quick to reconnect comes back during the shutdown and outlives it.
    """
    for server in _servers(broker):
        server.instance.close()
    for _session, handler in list(broker.sessions.values()):
        if handler is not None and handler.writer is not None:
            try:
                await asyncio.wait_for(handler.writer.close(), 1.0)
            except OSError:  # gone already, or not reading (TimeoutError): no matter
                pass
    try:
        await asyncio.wait_for(broker.shutdown(), timeout_s)
    except TimeoutError:
        _log.error('the embedded MQTT broker did not shut down within %g s', timeout_s)


def _servers(broker: Broker) -> list[Any]:
    try:
        return list(broker._servers.values())
    except AttributeError as exc:
        raise RuntimeError('cannot reach the listeners of amqtt (Broker._servers changed with '
                           'this amqtt version)') from exc


def _bound_port(broker: Broker) -> int:
    try:
        listener = next(s for s in _servers(broker) if s.listener_name == _LISTENER)
        return int(listener.instance.sockets[0].getsockname()[1])
    except (AttributeError, StopIteration, IndexError, TypeError) as exc:
        raise RuntimeError('cannot read the port amqtt listens on (Broker._servers changed '
                           'with this amqtt version)') from exc


def main(argv: list[str] | None = None) -> int:
    """Run the local broker as a process: print its URL line, serve until SIGINT/SIGTERM."""
    parser = argparse.ArgumentParser(
        prog='python -m agv_nodes.mqtt.broker',
        description='MQTT broker on 127.0.0.1 for the trucks and a VDA 5050 master (mosquitto '
                    'when installed, else the embedded amqtt); prints mqtt://127.0.0.1:PORT '
                    'when ready.')
    parser.add_argument('--port', type=int, default=0,
                        help='port to listen on (default: a free one)')
    parser.add_argument('--host', default=HOST,
                        help='address to listen on (default 127.0.0.1: this machine only; an '
                        "interface's address for trucks on other hosts)")
    parser.add_argument('--embedded', action='store_true',
                        help='the embedded amqtt broker even where mosquitto is installed')
    args = parser.parse_args(argv)
    if not 0 <= args.port <= 65535:
        parser.error(f'--port {args.port}: give 0 (any free port) or 1-65535')
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr,
                        format='%(name)s %(levelname)s: %(message)s')

    stop = threading.Event()

    def request_stop(signum: int, frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)
    broker = local_broker(port=args.port, host=args.host, embedded=args.embedded)
    if isinstance(broker, EmbeddedBroker) and not args.embedded:
        print(f'agv_nodes.mqtt.broker: {broker.name}', file=sys.stderr, flush=True)
    try:
        url = broker.start()
    except RuntimeError as exc:
        print(exc, file=sys.stderr)
        return 1
    try:
        print(url, flush=True)
        while not stop.wait(1.0):  # timed, so no platform can miss the signal in a blocked wait
            pass
    finally:
        broker.stop()
    return 0


if __name__ == '__main__':
    sys.exit(main())
