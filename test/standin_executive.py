"""A stand-in executive written from the docs alone: starts the truck, drives it, stops it.

Run against a graph launched without its executive (docs/hardware.md, "Standing in for the
executive"); it uses only what the docs give a driver:

- the record tables (msg_schemas/*.yaml, docs/records.md): it packs traction_command and
  route_command and reads traction_status itself, E2E counter and CRC-8/SAE-J1850 over data_id
  and bytes 1-15 as docs/records.md says; nothing of agv_nodes is imported;
- the topics (relative: traction/command, route/command, traction/status; /clock, and
  sim/progress/<name> so that the simulated world paces on it when named in its pace_nodes);
- the start-up contract (docs/hardware.md, "Starting a board: the start-up contract"): 00H every
  50 ms until traction_status shows the 00H taken (tripped with emergency_stop), then the
  demand; 00H again whenever a status shows the relay open with no 00H taken.

It is admitted by naming it in the readers' record_writers (traction: traction_command,
route_following: route_command). Timeline, in sim time: the contract until the relay closes,
then `--demand` % for `--drive` s, then 00H (emergency stop) until it is stopped. Each step is
a line on stdout: `standin: <what> at <sim s>`.

    python test/standin_executive.py --demand 30 --drive 6 [--ros-args -r __ns:=/agv2]
"""

from __future__ import annotations

import argparse
from pathlib import Path
import signal
import sys
from typing import Any

import yaml

SCHEMAS = Path(__file__).resolve().parents[1] / 'msg_schemas'
NAME = 'standin_executive'


# -- the record tables, read as a driver would ---------------------------------------------------
def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8/SAE-J1850: poly 1DH, init FFH, no reflection, xorout FFH (check 4BH)."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def _span(text: Any) -> tuple[int, int]:
    """Return (low, high) of a table's `byte` or `bits` entry: 3, or '0-2', or '6-7'."""
    if isinstance(text, int):
        return text, text
    a, b = (int(x) for x in str(text).split('-'))
    return min(a, b), max(a, b)


class Table:
    """One record's table: its fields' places and encodings, its data_id, protection."""

    def __init__(self, record: str, schemas: Path = SCHEMAS) -> None:
        doc = yaml.safe_load((schemas / f'{record}.yaml').read_text())
        self.name, self.topic, self.data_id = doc['record'], doc['topic'], int(doc['data_id'])
        self.protected = doc['kind'] == 'inter_processor'  # E2E: inter-processor records only
        self.period = doc['period_ms'] / 1000.0
        self.fields = doc['fields']
        self.counter = 0

    @staticmethod
    def _place(f: dict) -> tuple[int, Any]:
        """Return (first byte, 0-based; its bits: '0-7' unless the table says)."""
        return _span(f['byte'])[0] - 1, f.get('bits', '0-7')

    def pack(self, values: dict[str, Any]) -> bytes:
        """Return 16 bytes for `values` (missing fields: their table default), E2E sealed."""
        out = bytearray(16)
        for f in self.fields:
            value = values.get(f['name'], f.get('default', 0))
            enc = f['encoding']
            if enc == 'enum':
                value = f['values'][value] if isinstance(value, str) else int(value)
            value = int(value)
            first, bits = self._place(f)
            if enc in ('s16le', 'u16le'):  # two bytes, little endian
                out[first:first + 2] = (value & 0xFFFF).to_bytes(2, 'little')
                continue
            lo, hi = _span(bits)
            width = hi - lo + 1
            out[first] |= (value & ((1 << width) - 1)) << lo
        if self.protected:
            out[14] = self.counter
            out[15] = crc8_sae_j1850(bytes([self.data_id]) + bytes(out[:15]))
            self.counter = (self.counter + 1) & 0xFF
        return bytes(out)

    def unpack(self, data: bytes) -> dict[str, Any] | None:
        """Return the fields of 16 bytes (enums by name), or None when the CRC does not fit."""
        if len(data) != 16 or (self.protected and data[15] != crc8_sae_j1850(
                bytes([self.data_id]) + bytes(data[:15]))):
            return None
        fields: dict[str, Any] = {}
        for f in self.fields:
            first, bits = self._place(f)
            enc = f['encoding']
            if enc in ('s16le', 'u16le'):
                value = int.from_bytes(data[first:first + 2], 'little', signed=enc == 's16le')
            else:
                lo, hi = _span(bits)
                width = hi - lo + 1
                value = (data[first] >> lo) & ((1 << width) - 1)
                if enc == 'twos_complement' and value & (1 << (width - 1)):
                    value -= 1 << width
                if enc == 'enum':
                    value = {code: name for name, code in f['values'].items()}.get(value, value)
            fields[f['name']] = value
        return fields


# -- the start-up contract and the drive -----------------------------------------------------
def contract_demand(status: dict | None, wanted: int) -> int:
    """Return the demand to send: 00H until traction has taken one, then `wanted`.

    docs/hardware.md: 00H until a traction_status is heard, and while one shows the relay open
    (tripped) without emergency_stop (no 00H taken since it opened); otherwise the demand.
    """
    if status is None or (status['tripped'] and not status['emergency_stop']):
        return 0
    return wanted


class StandIn:
    """The executive's part the truck needs to move: traction and route commands, on /clock."""

    def __init__(self, demand: int, drive: float) -> None:
        self.command = Table('traction_command')
        self.route = Table('route_command')
        self.status_table = Table('traction_status')
        self.demand, self.drive = demand, drive
        self.status: dict | None = None
        self.bad_status = 0
        self.phase = 'start'  # start | drive | stop
        self.closed_at: float | None = None
        self.next_send = 0.0
        self.sent_00h = 0  # 00H records sent before traction showed one taken
        self.taken = False

    def on_status(self, data: bytes) -> None:
        """Take a traction_status record (one that fails its CRC is counted, never used)."""
        fields = self.status_table.unpack(data)
        if fields is None:
            self.bad_status += 1
            return
        if self.status is None:
            say(f'traction_status heard (tripped {fields["tripped"]}, '
                f'{fields["trip_cause"]})', None)
        self.status = fields

    def step(self, now: float) -> list[tuple[Table, bytes]] | None:
        """Return the records due at sim time `now` (every traction_command period)."""
        if now < self.next_send:
            return None
        self.next_send = now + self.command.period
        status = self.status
        if self.phase == 'start' and not self.taken and status is not None \
                and status['tripped'] and status['emergency_stop']:
            self.taken = True
            say(f'00H taken (status armed) after {self.sent_00h} sent', now)
        if self.phase == 'start' and status is not None and not status['tripped']:
            self.phase, self.closed_at = 'drive', now
            say('relay closed', now)
        if self.phase == 'drive' and now >= self.closed_at + self.drive:
            self.phase = 'stop'
            say('stop (00H)', now)
        demand = 0 if self.phase == 'stop' else contract_demand(status, self.demand)
        self.sent_00h += self.phase == 'start' and demand == 0
        return [(self.command, self.command.pack({'demand': demand, 'executive_priority': 1})),
                (self.route, self.route.pack({'mode': 'follow_wire'}))]


def say(what: str, now: float | None) -> None:
    """One line on stdout, flushed (the test reads them as they come)."""
    print(f'standin: {what}' + ('' if now is None else f' at {now:.3f}'), flush=True)


def main(argv: list[str] | None = None) -> int:
    """Run the stand-in until interrupted."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import UInt8MultiArray

    argv = sys.argv if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--demand', type=int, default=30, help='%% duty once started (1..80)')
    ap.add_argument('--drive', type=float, default=6.0, help='sim s at the demand, then 00H')
    ap.add_argument('--name', default=NAME, help='node name (what record_writers names)')
    args = ap.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    if not 1 <= args.demand <= 80:
        ap.error(f'--demand {args.demand}: traction_command.demand is -80..80 and 0 is 00H')

    context = rclpy.Context()
    # its own SIGINT/SIGTERM handling: stop spinning, then shut down in order
    rclpy.init(args=argv, context=context, signal_handler_options=SignalHandlerOptions.NO)
    running = [True]
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: running.__setitem__(0, False))
    node = rclpy.create_node(args.name, context=context)
    standin = StandIn(args.demand, args.drive)

    def keep_last(depth: int, latched: bool = False) -> QoSProfile:
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                          else DurabilityPolicy.VOLATILE)

    # writers offer the strongest QoS (docs/hardware.md): reliable, transient local
    pubs = {t.name: node.create_publisher(UInt8MultiArray, t.topic, keep_last(1, True))
            for t in (standin.command, standin.route)}
    progress = node.create_publisher(Clock, f'sim/progress/{args.name}', keep_last(5))
    node.create_subscription(UInt8MultiArray, standin.status_table.topic,
                             lambda msg: standin.on_status(bytes(msg.data)), keep_last(50))
    last_progress = [-1.0]

    def on_clock(msg: Clock) -> None:
        now = msg.clock.sec + msg.clock.nanosec * 1e-9
        if now <= 0.0:  # the world has not started
            return
        for table, raw in standin.step(now) or ():
            pubs[table.name].publish(UInt8MultiArray(data=list(raw)))
        if now - last_progress[0] >= 0.02:  # what it has handled, for the world's pacing
            last_progress[0] = now
            progress.publish(msg)

    node.create_subscription(Clock, '/clock', on_clock, keep_last(100))
    say(f'{node.get_fully_qualified_name()} up', None)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        while running[0]:
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
