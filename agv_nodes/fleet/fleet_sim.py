"""agv-fleet-sim: N whole 1983 trucks in lock step, each a VDA 5050 AGV on one MQTT broker.

For a master control of anyone's (openTCS's VDA 5050 driver, one's own): the trucks are the
lock-step fleet (agv_nodes.fleet.lockstep.Fleet: each truck its world core and seven node
cores, one floor, stepped in as many processes as there are cores), and each truck has its own
VDA 5050 face (agv_nodes.fleet.fleet_sim_truck: the bridge core the vda5050_bridge node runs,
its own MQTT client and last will). docs/fleet_simulator.md says how to point a master at it,
and what is simulated and what is not.

Simulated time is paced to the wall clock times `--time-factor` (0: as fast as it goes). The
sim steps a slice of SLICE simulated seconds, then gives each truck's bridge what its
communications wrote and what its master sent, then waits for the wall clock. The real-time
ratio achieved is logged and published on `<interface>/v2/<manufacturer>/fleet-sim/status`
every --status-period wall seconds, with the commands taken and rejected.

Each truck starts as a truck set down at its start marker and homed there: the simulator gives
its bridge an initPosition (actionId `fleet-sim-start`) before the master is heard, so its
first state names that node as lastNodeId.

While it runs a tester injects faults and adds or removes trucks through the control channel
(agv_nodes.fleet.fleet_sim_control: JSON on `.../fleet-sim/control`, or lines on stdin).
"""

from __future__ import annotations

from collections.abc import Callable
import json
import os
import queue
import sys
import threading
import time
from typing import Any
import uuid

from pydantic import BaseModel

from agv_nodes.fleet import fleet_sim_faults as faults
from agv_nodes.fleet import fleet_sim_records as records
from agv_nodes.fleet.fleet_sim_control import Command, CommandError, from_json, from_line
from agv_nodes.fleet.fleet_sim_options import SimOptions, options_from_args, parser, start_of
from agv_nodes.fleet.fleet_sim_truck import TruckFace
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.vda5050 import MAJOR, VERSION
from agv_nodes.vda5050.bridge import Outbox
from agv_nodes.vda5050.common import now as utc_now
from agv_nodes.vda5050.topics import topic
from agv_nodes.world.layout import layout_path, load_layout

SLICE = 0.02  # simulated s between the bridges' turns (a master's message waits at most this)
RESYNC_LAG = 1.0  # wall s behind the pace after which the pace starts afresh, not racing
FAULT_CALLS: dict[str, Callable[..., None]] = {
    'drive': faults.drive, 'radioStop': faults.radio_stop, 'blockedMarker': faults.blocked_marker}


class FleetSim:
    """See the module docstring."""

    def __init__(self, options: SimOptions, url: str,
                 log: Callable[[str], None] = lambda line: print(line, flush=True)) -> None:
        self.o, self.url, self.log = options, url, log
        self.layout = load_layout(layout_path(options.layout))
        self.graph = track_graph(self.layout)
        starts = [start_of(self.layout, marker) for marker in options.starts]
        # forked before any MQTT thread runs: the truck processes hold no paho state
        self.fleet = Fleet(options.layout, starts, seed=options.seed, names=options.serials,
                           processes=options.processes)
        self._seeds = len(options.serials)  # the next added truck's seed offset
        self.faces: dict[str, TruckFace] = {}
        self.faults: dict[str, set[str]] = {}
        prefix = f'{options.interface}/{MAJOR}/{options.manufacturer}/fleet-sim'
        self.control_topic, self.status_topic = f'{prefix}/control', f'{prefix}/status'
        self._commands: queue.SimpleQueue[tuple[str, bytes | str]] = queue.SimpleQueue()
        self.counts = {'commands': 0, 'rejected': 0}
        self.last_command, self.last_rejection = '', ''
        self.results: list[tuple[float, str, str]] = []  # (sim s, command, 'ok' or why not)
        # taps see every message a truck publishes: (truck, topic name, message, sim s)
        self.taps: list[Callable[[str, str, BaseModel, float], None]] = []
        self.quit = threading.Event()
        self._slice_samples = max(1, round(SLICE / self.fleet._dt))
        self._next_visualization = 0.0
        self.ratio = 0.0  # simulated s per wall s over the last status period
        self.control: MqttLink | None = None
        self.owner = uuid.uuid4().hex  # names this simulator's record taps in every process

    @property
    def now(self) -> float:
        """Simulated seconds."""
        return self.fleet.now

    # --- start and end ---------------------------------------------------------------------

    def start(self) -> None:
        """Connect every truck and the control channel; home each truck at its start."""
        self.control = MqttLink(self.url, f'{self.o.manufacturer}_fleet-sim')
        self.control.subscribe(self.control_topic, 1,
                               lambda _t, payload: self._commands.put(('json', payload)))
        self.control.connect()
        for name, marker in zip(self.o.serials, self.o.starts, strict=True):
            self._face(name, marker, wait=True)
        self.log(f'fleet-sim: {len(self.faces)} trucks on {self.url}, layout {self.layout.name}, '
                 f'{self.o.processes} processes, time factor {self.o.time_factor:g}; control: '
                 f'{self.control_topic} or stdin')

    def _face(self, name: str, marker: str, wait: bool) -> None:
        face = TruckFace(name, self.url, self.graph, manufacturer=self.o.manufacturer,
                         interface=self.o.interface, map_id=self.layout.name,
                         state_interval=self.o.state_interval)
        self.faces[name], self.faults[name] = face, set()
        self.fleet.query(name, records.tap, self.owner, name)
        face.connect(wait=wait)
        home = {'headerId': 0, 'timestamp': utc_now().isoformat(timespec='milliseconds'),
                'version': VERSION, 'manufacturer': self.o.manufacturer, 'serialNumber': name,
                'actions': [{'actionType': 'initPosition', 'actionId': 'fleet-sim-start',
                             'blockingType': 'HARD', 'actionParameters': [
                                 {'key': 'lastNodeId', 'value': marker}]}]}
        self._apply(name, face.bridge.on_message('instantActions', json.dumps(home), self.now))

    def close(self) -> None:
        """Say OFFLINE for every truck, disconnect, end the truck processes."""
        for face in self.faces.values():
            face.close()
        if self.control is not None:
            self.control.close()
        self.fleet.close()
        records.forget(self.owner)

    # --- running ---------------------------------------------------------------------------

    def command(self, text: str) -> None:
        """Queue a command line (as stdin gives it) for the simulator's thread."""
        self._commands.put(('line', text))

    def run(self, seconds: float | None = None) -> None:
        """Run, paced, for `seconds` of simulated time (None: until `quit`)."""
        end = None if seconds is None else self.now + seconds
        factor = self.o.time_factor
        wall0, sim0 = time.monotonic(), self.now
        status_wall, status_sim = wall0, sim0
        while not self.quit.is_set() and (end is None or self.now < end - 1e-9):
            self.slice()
            wall = time.monotonic()
            if factor > 0:
                ahead = (self.now - sim0) / factor - (wall - wall0)
                if ahead > 0:
                    time.sleep(ahead)
                elif ahead < -RESYNC_LAG:  # behind: go on from here at the pace, no race
                    wall0, sim0 = wall, self.now
            if wall - status_wall >= self.o.status_period:
                self.ratio = (self.now - status_sim) / (wall - status_wall)
                status_wall, status_sim = wall, self.now
                self.publish_status()

    def slice(self) -> None:
        """Step SLICE of simulated time; then the bridges, the control commands."""
        fleet = self.fleet
        for _ in range(self._slice_samples):
            fleet.step()
        now = self.now
        visualize = now + 1e-9 >= self._next_visualization
        if visualize:
            self._next_visualization = now + self.o.visualization_period
        tapped = records.take_all(fleet.query, list(self.faces), self.owner)
        for name, face in list(self.faces.items()):
            out = face.poll(now)  # first: a link just up says ONLINE before any state
            out.extend(face.read(tapped.get(name, ()), now))
            for text in fleet.take_notes(name):
                out.extend(face.bridge.on_report(text, now))
            if visualize:
                out.extend(face.visualization(fleet.query(name, faults.reference_pose)))
            self._apply(name, out)
        while not self._commands.empty():
            kind, payload = self._commands.get_nowait()
            self._take(kind, payload)

    def _apply(self, name: str, out: Outbox) -> None:
        for text in out.tasks:
            self.fleet.submit(name, text)
        face = self.faces[name]
        if face.link is not None and face.up:  # what is published
            for tap in self.taps:
                for topic_name, message in out.messages:
                    tap(name, topic_name, message, self.now)
        face.send(out)

    # --- the control channel ---------------------------------------------------------------

    def _take(self, kind: str, payload: bytes | str) -> None:
        self.counts['commands'] += 1
        try:
            command = from_json(payload) if kind == 'json' else from_line(str(payload))
            self.last_command = str(command)
            self._do(command)
        except (CommandError, KeyError, ValueError) as exc:
            self.counts['rejected'] += 1
            why = str(exc.args[0]) if isinstance(exc, KeyError) else str(exc)
            self.last_rejection = f'{str(payload)[:200]!r}: {why}'
            self.results.append((self.now, str(payload), f'rejected: {why}'))
            self.log(f'fleet-sim: rejected {self.last_rejection}')
        else:
            self.results.append((self.now, str(command), 'ok'))
            self.log(f'fleet-sim: {command}: ok at {self.now:.2f} s')
        self.publish_status()

    def _do(self, c: Command) -> None:
        if c.verb == 'quit':
            self.quit.set()
            return
        if c.verb == 'status':
            return
        if c.verb == 'add':
            start = start_of(self.layout, c.start)  # ValueError names the marker
            topic(self.o.manufacturer, c.truck, 'state', interface=self.o.interface)
            self.fleet.add(c.truck, start, seed=self.o.seed + self._seeds)
            self._seeds += 1
            self._face(c.truck, c.start, wait=False)
            return
        if c.truck not in self.faces:
            raise KeyError(f'no truck {c.truck!r} (trucks: {", ".join(self.faces)})')
        face, on = self.faces[c.truck], c.verb == 'fault'
        if c.verb == 'remove':
            face.close()
            self.fleet.query(c.truck, records.untap, self.owner, c.truck)
            self.fleet.remove(c.truck)
            del self.faces[c.truck], self.faults[c.truck]
        elif c.fault == 'brokerLink':
            face.cut(self.now) if on else face.mend()
        elif c.fault == 'blockedMarker':
            self.fleet.query(c.truck, faults.blocked_marker, on, c.marker)
        else:
            self.fleet.query(c.truck, FAULT_CALLS[c.fault], on)
        if c.verb != 'remove':
            name = f'{c.fault} {c.marker}'.strip()
            self.faults[c.truck].add(name) if on else self.faults[c.truck].discard(name)

    def status(self) -> dict[str, Any]:
        """Return what the status topic carries (the simulator's diagnostics)."""
        return {'time': round(self.now, 3), 'timeFactor': self.o.time_factor,
                'realTimeRatio': round(self.ratio, 3), 'trucks': list(self.faces),
                'faults': {name: sorted(f) for name, f in self.faults.items() if f},
                'linksUp': sum(f.link is not None and f.link.connected
                               for f in self.faces.values()),
                'collisions': len(self.fleet.collisions), **self.counts,
                'recordsRejected': sum(r.rejected for f in self.faces.values()
                                       for r in f.records.readers.values()),
                'lastCommand': self.last_command, 'lastRejection': self.last_rejection}

    def publish_status(self) -> None:
        """Publish the status (retained) and log it in one line."""
        doc = self.status()
        if self.control is not None:
            self.control.publish(self.status_topic, json.dumps(doc), qos=1, retain=True)
        self.log(f'fleet-sim: t {doc["time"]:.1f} s, {doc["realTimeRatio"]:.2f}x real time '
                 f'(asked {self.o.time_factor:g}x), {len(doc["trucks"])} trucks, '
                 f'{doc["linksUp"]} links up, {doc["commands"]} commands '
                 f'({doc["rejected"]} rejected)')


def _read_stdin(sim: FleetSim) -> None:
    for line in sys.stdin:
        if line.strip():
            sim.command(line)


def main(argv: list[str] | None = None) -> int:
    """Entry point: agv-fleet-sim [options] (agv-fleet-sim --help)."""
    args = parser().parse_args(argv)
    try:
        options, url, broker = options_from_args(args, os.cpu_count() or 1)
    except ValueError as exc:
        print(f'agv-fleet-sim: {exc}', file=sys.stderr)
        return 2
    if broker is not None:
        print(f'agv-fleet-sim: MQTT broker {url} ({broker.name}, ends with agv-fleet-sim)',
              flush=True)
    try:
        sim = FleetSim(options, url)
        try:
            sim.start()
            threading.Thread(target=_read_stdin, args=(sim,), daemon=True).start()
            sim.run(args.seconds)
        except KeyboardInterrupt:
            pass
        finally:
            sim.close()
    finally:
        if broker is not None:
            broker.stop()
    return 0


if __name__ == '__main__':
    sys.exit(main())
