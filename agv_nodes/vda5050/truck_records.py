"""The truck's records a bridge reads, turned into the facts BridgeCore takes.

The bridge node subscribes to these records as one more reader (agv_nodes.vda5050.bridge_node),
a lock-step fleet taps them (agv_nodes.harness); either hands each decoded record to
BridgeCore.on_record, which takes it here:

- position_sensor_status: a new recognition (its `recognitions` counter moved) in the
  navigating table is a card read: a location's identity, or EDIM for a stop marker's centre
  (Baker 1983, App. B.1 UCTAB). Heartbeats repeat the last recognition and are not reads.
- load_status: the two conveyors' load sensors (Baker 1983, 6.5).
- traction_status: the radio stop, the bumper and manual control (the 1983 truck's records
  carry no emergency stop button: traction's emergency_stop is the executive's 00H stop).
- wheel_odometry: the driven wheels' counters, for dead reckoning.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from agv_nodes.markers import EDIM
from agv_nodes.records import codec
from agv_nodes.records.ports import RecordReader
from agv_nodes.vda5050.whereabouts import TractionFacts

if TYPE_CHECKING:
    from agv_nodes.vda5050.bridge import BridgeCore, Outbox

RECORDS = ('position_sensor_status', 'load_status', 'traction_status', 'wheel_odometry')
NONE = 0xFF  # position_sensor_status identity: no card recognised yet


class RecordFacts:
    """Reads RECORDS into BridgeCore's typed methods (see the module docstring)."""

    def __init__(self) -> None:
        self._recognitions: int | None = None  # the sensor's counter last seen
        self.reads = 0  # cards read (recognitions in the navigating table)

    def feed(self, core: BridgeCore, name: str, fields: dict[str, Any], now: float) -> Outbox:
        """Give `core` what record `name` (decoded `fields`) says."""
        if name == 'wheel_odometry':  # first: half the records a bridge reads
            return core.on_wheels(fields['left_distance'], fields['right_distance'],
                                  fields['left_speed'], fields['right_speed'], now)
        if name == 'position_sensor_status':
            count, before = fields['recognitions'], self._recognitions
            self._recognitions = count
            identity = fields['identity']
            new = count != before if before is not None else bool(fields['recognised'])
            if not new or fields['table'] != 'navigating' or identity == NONE:
                from agv_nodes.vda5050.bridge import Outbox  # the bridge imports this module
                return Outbox()
            self.reads += 1
            return core.on_marker_read(None if identity == EDIM else identity, now)
        if name == 'load_status':
            return core.on_loads(bool(fields['load_first']), bool(fields['load_second']), now)
        if name == 'traction_status':
            # Its emergency_stop flag is the executive's commanded stop (00H, GETREF), made at
            # every stop: no emergency stop button's.
            return core.on_traction(TractionFacts(
                radio_stop=bool(fields['radio_stop']), bumper=bool(fields['bumper']),
                manual=bool(fields['manual'])), now)
        raise ValueError(f'record {name!r}: the bridge reads only {", ".join(RECORDS)}')


class RecordTap:
    """A lock-step harness's tap (Harness.taps) that gives a bridge core the truck's records.

    Each record of RECORDS is judged by a reader of its own, as the bridge node's readers judge
    them (a rejected one is counted and dropped); what the core answers waits in `take()`,
    for the caller to send (tasks to the truck, messages to the master):

        tap = RecordTap(core); harness.taps.append(tap)
        ... after each step: apply(tap.take())
    """

    def __init__(self, core: BridgeCore) -> None:
        from agv_nodes.vda5050.bridge import Outbox  # the bridge imports this module
        self.core = core
        self.readers = {name: RecordReader(codec()[name], 'e2e' if codec()[name].protected
                                           else 'none') for name in RECORDS}
        self._out = Outbox()

    def __call__(self, record: str, raw: bytes, now: float) -> None:
        """Take one record as the harness delivers it (its 16 bytes, at sim time `now`)."""
        self.read(record, raw, now, now)

    def read(self, record: str, raw: bytes, sent_at: float, now: float) -> None:
        """Take one record sent at `sent_at` on the truck's clock, for the core at `now`.

        The reader judges it on the truck's clock; the core takes it on its own (a fleet's
        added truck counts from its power-on, its bridge from the simulator's start).
        """
        reader = self.readers.get(record)
        if reader is not None and \
                (fields := reader.accept(raw, round(sent_at * 1e9))) is not None:
            self._out.extend(self.core.on_record(record, fields, now))

    def take(self) -> Outbox:
        """Return what the core answered since the last take (tasks, messages), and forget it."""
        from agv_nodes.vda5050.bridge import Outbox
        out, self._out = self._out, Outbox()
        return out
