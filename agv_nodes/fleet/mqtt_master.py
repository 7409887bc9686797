"""The dispatcher as a VDA 5050 master control over MQTT, without ROS.

`MqttMaster` puts a Dispatcher (agv_nodes.fleet.dispatcher) on an MQTT link
(agv_nodes.mqtt.client.MqttLink). For each truck it subscribes `state` and `connection`
(`uagv/v2/<manufacturer>/<serialNumber>/...`, with the QoS of agv_nodes.vda5050.topics: 0 and
1), and it publishes the dispatcher's `order` and `instantActions` with theirs (0, not retained).

What a truck sends is parsed with the package's models (agv_nodes.vda5050.codec.parse) and
checked before the dispatcher sees it. It is rejected, counted by reason, and never acted on
when it is:
- `invalid`: not JSON, or not a valid VDA 5050 state or connection message;
- `foreign`: its header names another manufacturer or truck than its topic, or a protocol
  version other than 2.x;
- `unknown node`: a state whose lastNodeId is not a node of the track graph.
A truck whose connection is CONNECTIONBROKEN (its last will) or OFFLINE is sent nothing until it
is ONLINE again (Dispatcher.set_online): no new work, no updates, no initPosition. While the
master's own link is down it does not step the dispatcher: a message published then would be
lost, and the dispatcher would plan on orders no truck has.

paho calls back on its network thread; the callbacks only put the payload in a queue, which
`step` (the caller's thread, e.g. a ROS timer) empties. Nothing else is shared between threads.

Transport orders come as text (`parse_transport`, syntax TRANSPORT_SYNTAX) and are answered
with report lines; `progress` tells each one's way on: queued, assigned, done or failed.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection
from functools import partial
import queue
import re

from pydantic import BaseModel

from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.vda5050 import INTERFACE
from agv_nodes.vda5050.codec import MessageError, parse, to_json
from agv_nodes.vda5050.connection import Connection, ConnectionState
from agv_nodes.vda5050.state import State
from agv_nodes.vda5050.topics import TOPICS, topic

TRANSPORT_SYNTAX = "'[ID:] SOURCE to DESTINATION' (stations), e.g. 'W0 to W2' or 'job7: W0 to W2'"
INBOUND: dict[str, type[State | Connection]] = {'state': State, 'connection': Connection}
OUTBOUND = ('order', 'instantActions')
# The dispatcher's own order ids (parking, making way, initPosition): no transport may take one.
RESERVED_PREFIXES = ('park-', 'yield-', 'init-')
_TRANSPORT = re.compile(r'\s*(?:(?P<id>[^:\s]+)\s*:\s*)?(?P<source>\S+)\s+(?i:to)\s+'
                        r'(?P<destination>\S+)\s*')
_ID = re.compile(r'[A-Za-z0-9_.-]{1,64}')  # it becomes VDA 5050 orderId and actionIds
_REASON_CHARS = 300  # of a rejected message's problem, in the last-rejection text


class TransportError(ValueError):
    """A transport order text that cannot be taken; the message says why."""


def stations(graph: TrackGraph) -> list[str]:
    """Return the stations of `graph` a transport can name (those with a stop marker)."""
    return sorted({n.station for n in graph.nodes.values() if n.stoppable and n.station})


def parse_transport(text: str, known: Collection[str], default_id: str) -> TransportOrder:
    """Return the transport order `text` asks for (TRANSPORT_SYNTAX).

    `known` are the stations a transport may name; `default_id` is the id of a text that gives
    none. TransportError says what is wrong: the syntax, the id, or a station.
    """
    if not text.strip():
        raise TransportError(f'empty; expected {TRANSPORT_SYNTAX}')
    match = _TRANSPORT.fullmatch(text)
    if match is None:
        raise TransportError(f'expected {TRANSPORT_SYNTAX}')
    order_id = match['id'] or default_id
    if not _ID.fullmatch(order_id):
        raise TransportError(f'id {order_id!r}: use 1-64 letters, digits, _ . or -')
    if order_id.startswith(RESERVED_PREFIXES):
        raise TransportError(f'id {order_id!r}: ids starting {", ".join(RESERVED_PREFIXES)} '
                             "are the dispatcher's own")
    for station in (match['source'], match['destination']):
        if station not in known:
            raise TransportError(f'unknown station {station!r} (stations: '
                                 f'{", ".join(sorted(known))})')
    if match['source'] == match['destination']:
        raise TransportError(f'source and destination are both {match["source"]}')
    return TransportOrder(order_id, match['source'], match['destination'])


def rejected_line(text: str, reason: str) -> str:
    """Return the report line of a transport text that was not taken."""
    return f'rejected {text.strip()!r}: {reason}'


class MqttMaster:
    """See the module docstring."""

    def __init__(self, dispatcher: Dispatcher, link: MqttLink, *,
                 interface: str = INTERFACE) -> None:
        """Master the dispatcher's trucks on `link` (connected or not: it subscribes either way).

        The trucks, their manufacturer and the track graph are the dispatcher's.
        """
        self.dispatcher = dispatcher
        self.link = link
        self.manufacturer = dispatcher.manufacturer
        self.trucks = dispatcher.trucks
        self.stations = stations(dispatcher.graph)
        self._topics = {truck: {name: topic(self.manufacturer, truck, name, interface=interface)
                                for name in (*INBOUND, *OUTBOUND)} for truck in self.trucks}
        self._inbox: queue.SimpleQueue[tuple[str, str, bytes]] = queue.SimpleQueue()
        self.states: dict[str, State] = {}  # each truck's last state taken
        self.connection: dict[str, ConnectionState] = {}  # each truck's last connection state
        self.rejected: Counter[str] = Counter()  # messages from trucks, by reason
        self.last_rejection = ''  # the last truck message rejected, and why
        self.rejecting = False  # True while the last truck message taken was rejected
        self.sent: Counter[str] = Counter()  # messages published, by topic name
        self.dropped = 0  # QoS 0 messages the link could not send
        self._asked = False  # stateRequest sent on this connection
        self.transports_rejected = 0
        self._ids: set[str] = set()  # every transport id taken
        self._serial = 0
        self._told: dict[str, str] = {}  # transport id -> what its last report line said
        for truck in self.trucks:
            for name in INBOUND:
                # on paho's thread: only hand the payload over (see the module docstring)
                self.link.subscribe(self._topics[truck][name], TOPICS[name].qos,
                                    partial(self._hand_over, truck, name))

    def _hand_over(self, truck: str, name: str, _topic: str, payload: bytes) -> None:
        """On paho's thread: only hand the payload over (see the module docstring)."""
        self._inbox.put((truck, name, payload))

    # -- transports ----------------------------------------------------------------------------
    def submit(self, text: str) -> str:
        """Take a transport order as text; return its report line (accepted or rejected).

        A text without an id gets the next free one of t1, t2, ...
        """
        serial = self._serial + 1
        while f't{serial}' in self._ids:  # a client may have named one so
            serial += 1
        default_id = f't{serial}'
        try:
            transport = parse_transport(text, self.stations, default_id)
            if transport.id in self._ids:
                raise TransportError(f'id {transport.id!r} is taken already')
            self.dispatcher.submit(transport)
        except ValueError as exc:  # TransportError, or a station the dispatcher refuses
            self.transports_rejected += 1
            return rejected_line(text, str(exc))
        self._ids.add(transport.id)
        if transport.id == default_id:
            self._serial = serial
        self._told[transport.id] = 'accepted'
        return f'{transport.id}: accepted: {transport.source} to {transport.destination}'

    def progress(self) -> list[str]:
        """Return the report lines of what became of the transports since the last call.

        After `accepted` each transport is `queued` when it has to wait for a truck (said
        once), then `assigned to <truck>`, then `done (<truck>)` or `failed (<truck>): <why>`. An
        assignment is said before its end even when the dispatcher did both in one step.
        """
        d = self.dispatcher
        waiting = {t.id for t in d.queue}
        done, failed = set(d.done), set(d.failed)
        lines = []
        for tid, told in list(self._told.items()):
            truck = d.assignments.get(tid)
            if told == 'accepted' and tid in waiting:
                lines.append(f'{tid}: queued: no idle truck can take it yet')
                self._told[tid] = 'queued'
            if truck is None:
                continue
            if self._told[tid] in ('accepted', 'queued'):
                lines.append(f'{tid}: assigned to {truck}')
            end = 'done' if tid in done else 'failed' if tid in failed else ''
            if end:
                why = f': {d.failures[tid]}' if end == 'failed' and tid in d.failures else ''
                lines.append(f'{tid}: {end} ({truck}){why}')
                del self._told[tid]
            else:
                self._told[tid] = 'assigned'
        return lines

    # -- the trucks ----------------------------------------------------------------------------
    def take(self, now: float) -> int:
        """Feed the dispatcher what the trucks sent since the last call; return how many."""
        count = 0
        while True:
            try:
                truck, name, payload = self._inbox.get_nowait()
            except queue.Empty:
                return count
            count += 1
            self._take(truck, name, payload, now)

    def _take(self, truck: str, name: str, payload: bytes, now: float) -> None:
        self.rejecting = False  # until this one is
        try:
            message = parse(INBOUND[name], payload)
        except MessageError as exc:
            self._reject(truck, name, 'invalid', str(exc))
            return
        if (message.manufacturer, message.serial_number) != (self.manufacturer, truck) \
                or message.version.split('.')[0] != '2':
            self._reject(truck, name, 'foreign', f'header {message.manufacturer}/'
                         f'{message.serial_number} version {message.version} on the topic of '
                         f'{self.manufacturer}/{truck}')
            return
        if isinstance(message, Connection):
            self.connection[truck] = message.connection_state
            self.dispatcher.set_online(truck, message.connection_state == ConnectionState.ONLINE)
            return
        assert isinstance(message, State)
        node = message.last_node_id
        if node and node not in self.dispatcher.graph.nodes:
            self._reject(truck, name, 'unknown node', f'lastNodeId {node!r} is not a node of '
                         'the track graph')
            return
        self.states[truck] = message
        self.dispatcher.on_state(truck, message, now)

    def _reject(self, truck: str, name: str, reason: str, problem: str) -> None:
        self.rejected[reason] += 1
        self.rejecting = True
        self.last_rejection = f'{truck} {name}: {reason}: {problem[:_REASON_CHARS]}'

    def online(self, truck: str) -> bool:
        """Return False for a truck whose last connection message was not ONLINE."""
        return self.connection.get(truck, ConnectionState.ONLINE) == ConnectionState.ONLINE

    # -- to the trucks -------------------------------------------------------------------------
    def step(self, now: float) -> list[tuple[str, str, BaseModel]]:
        """Take what the trucks sent, step the dispatcher, publish its messages; return them.

        With the link down nothing is stepped (see the module docstring): an empty list.
        """
        self.take(now)
        if not self.link.connected:
            self._asked = False
            return []
        out = [] if self._asked else self.dispatcher.state_requests()
        self._asked = True  # each (re)connection: where is every truck now?
        out += self.dispatcher.step(now)
        for truck, name, message in out:
            spec = TOPICS[name]
            if self.link.publish(self._topics[truck][name], to_json(message), spec.qos,
                                 spec.retain):
                self.sent[name] += 1
            else:  # lost in the moment the link went down; the truck's state will show it
                self.dropped += 1
        return out

    def counts(self) -> dict[str, int]:
        """Return the numbers a diagnostics row shows (transports, trucks, messages)."""
        d = self.dispatcher
        return {'queue': len(d.queue), 'assignments': len(d.assignments), 'done': len(d.done),
                'failed': len(d.failed), 'deadlocks': len(d.deadlocks),
                'conflicts': len(d.conflicts), 'transports rejected': self.transports_rejected,
                'messages rejected': sum(self.rejected.values()),
                **{f'messages rejected {k}': v for k, v in sorted(self.rejected.items())},
                'orders sent': self.sent['order'],
                'instant actions sent': self.sent['instantActions'],
                'messages dropped': self.dropped,
                'trucks heard': len(self.states),
                'trucks online': sum(self.online(t) for t in self.trucks)}
