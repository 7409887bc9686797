"""One truck's VDA 5050 bridge, without ROS or MQTT: messages in, tasks and messages out.

A master control (openTCS, or the dispatcher) sends `order` and `instantActions`; the bridge
validates them (6.6.4.1: a message that is not valid VDA 5050 is a validationError naming each
offending field), hands them to the order flow (agv_nodes.vda5050.order_flow) which turns them
into tasks in the truck's task language, and reads the truck's progress back from the lines
its communications node writes (agv_nodes.communications.report_line), the radio path of Baker
1983, 3.3. It answers with `state` on every change and at least every `state_interval`
seconds (6.10), `connection` (6.14) and the retained `factsheet` (6.15).

What the truck's records say comes in by typed methods, the same facts from the graph (the
bridge node reads the records over DDS) or from a lock-step fleet (agv_nodes.harness):

- on_marker_read(location, now): a card the position sensor read while navigating
  (position_sensor_status): a location card's identity, or None for a stop marker's centre.
  It is placed on the order's way (agv_nodes.vda5050.whereabouts) and becomes lastNodeId.
- on_wheels(left_mm, right_mm, left_speed, right_speed, now): the wheel_odometry counters;
  agvPosition and velocity are dead reckoning from the last node read.
- on_loads(first, second, now): load_status's two conveyors: `loads`.
- on_traction(TractionFacts, now): traction's radio stop, bumper and manual control
  (traction_status): safetyState (eStop REMOTE, fieldViolation) and operatingMode.
- on_record(name, fields, now): any of those records decoded, taken by the method above that
  reads it (RECORDS names them); what a reader of the graph's records calls.

BridgeCore(graph, manufacturer, serial_number, factsheet, state_interval, *, map_id, electruk,
visualization_interval): `map_id` is agvPosition's mapId (the layout's name), `electruk` the
world's Electruk parameters whose wheels the counters are of (default: the package's), and
`visualization_interval` the seconds between visualization messages from tick (0: none).

The truck models no battery: batteryState reports a full charge, not charging.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
import json
from typing import Any

from pydantic import BaseModel

from agv_nodes.communications.report_line import (
    STATE_WORDS,
    Aborted,
    Paused,
    Progress,
    Queued,
    read_report,
)
from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.vda5050 import VERSION
from agv_nodes.vda5050.codec import MessageError, parse
from agv_nodes.vda5050.common import now as utc_now
from agv_nodes.vda5050.connection import Connection, ConnectionState
from agv_nodes.vda5050.order import InstantActions, Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.vda5050.state import (
    AgvPosition,
    BatteryState,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    Info,
    InfoLevel,
    Load,
    OperatingMode,
    SafetyState,
    State,
    Visualization,
)
from agv_nodes.vda5050.truck_factsheet import MIN_STATE_INTERVAL
from agv_nodes.vda5050.truck_records import RecordFacts
from agv_nodes.vda5050.whereabouts import TractionFacts, Whereabouts
from agv_nodes.world.settings import WorldParams

INBOUND = {'order': Order, 'instantActions': InstantActions}
CONVEYORS = ('first', 'second')  # the loadPositions of the factsheet: the two conveyors


@dataclass
class Outbox:
    """What one input makes the bridge do: tasks for the truck, messages for the master."""

    tasks: list[str] = field(default_factory=list)
    messages: list[tuple[str, BaseModel]] = field(default_factory=list)  # (topic name, message)

    def extend(self, other: Outbox) -> None:
        """Take `other`'s tasks and messages after this one's."""
        self.tasks += other.tasks
        self.messages += other.messages


class BridgeCore:
    """See the module docstring."""

    def __init__(self, graph: TrackGraph, manufacturer: str, serial_number: str,
                 factsheet: Callable[[int], BaseModel] | None = None,
                 state_interval: float = 30.0, *, map_id: str = 'demo_1983',
                 electruk: Any = None, visualization_interval: float = 1.0) -> None:
        self.flow = OrderFlow(graph)
        e = electruk or WorldParams().electruk  # the wheels the counters are of
        self.where = Whereabouts(graph, e.track, e.wheelbase, map_id)
        self.records = RecordFacts()
        self.visualization_interval = visualization_interval  # s; 0: no visualization
        self._last_visualization = -float('inf')
        self._placed = ''  # the flow's lastNodeId the whereabouts were last set to
        self._loads: list[Load] | None = None  # None until load handling is heard
        self._traction = TractionFacts()
        self.manufacturer, self.serial_number = manufacturer, serial_number
        self._factsheet = factsheet
        self.state_interval = state_interval
        self._header_ids: dict[str, int] = {}
        self._rejections: list[Error] = []  # validation errors, until an order is accepted
        self._last_state = -float('inf')  # monotonic s of the last state sent
        self._held = False  # a change not sent yet (minStateInterval)
        self._gap: Info | None = None  # the last outage of the broker connection
        self.counts = {'orders': 0, 'instant_actions': 0, 'invalid': 0, 'reports': 0}
        self.last_invalid = ''  # what was wrong with the last message, while it was the last

    # --- from the master ---------------------------------------------------------------------

    def on_message(self, name: str, payload: bytes | str, now: float) -> Outbox:
        """Take an MQTT message of topic `name` ('order' or 'instantActions')."""
        try:
            message = parse(INBOUND[name], payload)
        except MessageError as exc:
            self.counts['invalid'] += 1
            self.last_invalid = str(exc)
            self._rejections = [self._validation_error(name, payload, exc)]
            return self._state(now)
        self.last_invalid = ''
        if isinstance(message, Order):
            self.counts['orders'] += 1
            outcome = self.flow.on_order(message)
            if outcome.verdict in ('accepted', 'updated'):
                self._rejections = []
        else:
            self.counts['instant_actions'] += 1
            outcome = self.flow.on_instant_actions(message)
        out = Outbox(tasks=list(outcome.tasks))
        if outcome.publish_factsheet and self._factsheet is not None:
            out.messages.append(('factsheet', self._factsheet(self._next_id('factsheet'))))
        if outcome.verdict != 'ignored' or outcome.publish_state:
            out.extend(self._state(now))
        return out

    def _validation_error(self, name: str, payload: bytes | str, exc: MessageError) -> Error:
        refs = [ErrorReference(reference_key='topic', reference_value=name)]
        try:
            header = json.loads(payload).get('headerId')
        except (ValueError, AttributeError):
            header = None
        if isinstance(header, int):
            refs.append(ErrorReference(reference_key='headerId', reference_value=str(header)))
        refs += [ErrorReference(reference_key=path, reference_value=problem)
                 for path, problem in exc.problems]
        return Error(error_type='validationError', error_references=refs,
                     error_description=str(exc), error_level=ErrorLevel.WARNING)

    # --- from the truck ----------------------------------------------------------------------

    def on_report(self, line: str, now: float) -> Outbox:
        """Take a comms/report line; a change of the truck's state is sent as state."""
        report = read_report(line)
        if report is None:
            return Outbox()
        self.counts['reports'] += 1
        if isinstance(report, Paused):  # the executive's word, not the request (startPause)
            return self._state(now) if self.flow.truck_paused(report.pause) else Outbox()
        if isinstance(report, Queued | Aborted):
            text = report.text if isinstance(report, Queued) else 'abort'
            return self._state(now) if self.flow.task_queued(report.task_id, text) else Outbox()
        assert isinstance(report, Progress)
        outcome = self.flow.task_state(report.task_id, STATE_WORDS[report.state],
                                       report.step or 0, report.cause, report.last_marker)
        out = Outbox(tasks=list(outcome.tasks))  # an abort after a failed task
        if outcome:
            out.extend(self._state(now))
        return out

    def on_marker_read(self, location: int | None, now: float) -> Outbox:
        """Take a card read while navigating: a location's identity, None a stop marker."""
        self._sync()
        node = self.where.place(location, self.flow.ahead())
        if node is None or not self.flow.node_read(node):
            return Outbox()
        return self._state(now)

    def on_wheels(self, left_mm: int, right_mm: int, left_speed: int, right_speed: int,
                  now: float) -> Outbox:
        """Take the wheel counters (wheel_odometry: wrapping mm, mm/s) for agvPosition."""
        self._sync()
        self.where.on_wheels(left_mm, right_mm, left_speed, right_speed)
        return Outbox()

    def on_loads(self, first: bool, second: bool, now: float) -> Outbox:
        """Take the conveyors' load sensors (load_status); a change is sent as state."""
        loads = [Load(load_position=name) for name, there in zip(CONVEYORS, (first, second),
                                                                 strict=True) if there]
        if loads == self._loads:
            return Outbox()
        self._loads = loads
        return self._state(now)

    def on_traction(self, facts: TractionFacts, now: float) -> Outbox:
        """Take traction's stops and mode (traction_status); a change is sent as state."""
        if facts == self._traction:
            return Outbox()
        self._traction = facts
        return self._state(now)

    def on_record(self, name: str, fields: dict[str, Any], now: float) -> Outbox:
        """Take one decoded record of RECORDS by the typed method that reads it."""
        return self.records.feed(self, name, fields, now)

    def reconnected(self, gap_s: float | None, now: float) -> Outbox:
        """Say ONLINE, the factsheet and the state after (re)connecting; report the gap.

        The truck goes on with the tasks it has while the broker is gone: it finishes the
        released base and stops at the decision point. The master learns how long it heard
        nothing from the state's information (6.10.6: for visualization and debugging).
        """
        if gap_s is not None:
            self._gap = Info(info_type='brokerConnectionGap', info_level=InfoLevel.INFO,
                             info_description=f'no connection to the broker for {gap_s:.1f} s; '
                             'the truck went on with the tasks it had')
        out = Outbox(messages=[('connection', self.connection(ConnectionState.ONLINE))])
        fact = self.factsheet()  # retained: a restarted broker has lost it
        if fact is not None:
            out.messages.append(('factsheet', fact))
        out.extend(self.state_now(now))
        return out

    def tick(self, now: float) -> Outbox:
        """Send a held-back state, or one when `state_interval` passed without (6.10).

        A change within the factsheet's minStateInterval of the last state waits for this.
        """
        since = now - self._last_state
        out = Outbox()
        if (self._held and since >= MIN_STATE_INTERVAL) or since >= self.state_interval:
            out = self._state(now)
        if self.visualization_interval and \
                now - self._last_visualization >= self.visualization_interval:
            self._last_visualization = now
            out.messages.append(('visualization', self.visualization()))
        return out

    def visualization(self) -> Visualization:
        """Return the visualization message (6.13): agvPosition and velocity now."""
        self._sync()
        return Visualization(**self.header('visualization'), agv_position=self.position(),
                             velocity=self.where.velocity())

    def position(self) -> AgvPosition:
        """Return agvPosition: the last node read and dead reckoning since (whereabouts)."""
        self._sync()
        return self.where.position()

    def _sync(self) -> None:
        """Set the whereabouts to the flow's lastNodeId where that has changed.

        The flow moves lastNodeId on the truck's reports too (a location passed, a stop
        reached, initPosition): the truck is at that node when it does.
        """
        if self.flow.last_node_id != self._placed:
            self._placed = self.flow.last_node_id
            self.where.at_node(self._placed)

    def state_now(self, now: float) -> Outbox:
        """Send state now (on connecting: the master learns where the truck stands)."""
        self._last_state = -float('inf')
        return self._state(now)

    # --- to the master -----------------------------------------------------------------------

    def _next_id(self, topic: str) -> int:
        """Return the next headerId of a topic (6.4: counted per topic, from 0)."""
        n = self._header_ids.get(topic, -1) + 1
        self._header_ids[topic] = n
        return n

    def header(self, topic: str, timestamp: datetime | None = None) -> dict[str, Any]:
        """Return the header fields of the next message on `topic`."""
        return {'header_id': self._next_id(topic), 'timestamp': timestamp or utc_now(),
                'version': VERSION, 'manufacturer': self.manufacturer,
                'serial_number': self.serial_number}

    def state(self) -> State:
        """Return the truck's state now (the next headerId of the state topic)."""
        fields = self.flow.state_fields()
        fields['errors'] = [*self._rejections, *fields.get('errors', [])]
        if self._gap is not None:
            fields['information'] = [*(fields.get('information') or []), self._gap]
        t = self._traction
        e_stop = EStop.MANUAL if t.e_stop else EStop.REMOTE if t.radio_stop else EStop.NONE
        return State(**self.header('state'), **fields, agv_position=self.position(),
                     velocity=self.where.velocity(), loads=self._loads,
                     distance_since_last_node=self.where.since if self.where.initialized
                     else None,
                     battery_state=BatteryState(battery_charge=100.0, charging=False),
                     operating_mode=OperatingMode.MANUAL if t.manual
                     else OperatingMode.AUTOMATIC,
                     safety_state=SafetyState(e_stop=e_stop, field_violation=t.bumper))

    def _state(self, now: float) -> Outbox:
        """Send state now, or at the next tick when one went out under minStateInterval ago."""
        if now - self._last_state < MIN_STATE_INTERVAL:
            self._held = True  # the changes of one burst of reports go out as one state
            return Outbox()
        self._last_state, self._held = now, False
        return Outbox(messages=[('state', self.state())])

    def connection(self, connection_state: ConnectionState) -> Connection:
        """Return a connection message (ONLINE, OFFLINE, or the last will's CONNECTIONBROKEN)."""
        return Connection(**self.header('connection'), connection_state=connection_state)

    def factsheet(self) -> BaseModel | None:
        """Return the factsheet to publish (retained) after connecting, if the bridge has one."""
        return self._factsheet(self._next_id('factsheet')) if self._factsheet else None
