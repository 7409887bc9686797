"""agv-fleet-sim under a master over a real broker: the real-time ratio it holds, message checks.

For each row (trucks, time factor) the bench starts a mosquitto of its own, agv-fleet-sim's
FleetSim on it (the trucks on fleet_1983_n<N>, at its parking places, in --processes
processes), and drives the trucks with the package's dispatcher as a VDA 5050 master over MQTT
(agv_nodes.fleet.mqtt_master: a load per truck sent round, as bench/fleet_bench.py's
programme), stepped every 0.1 wall s in a thread of its own. A third client subscribes to
every truck topic and checks each message against the standard's JSON schema
(test/data/vda5050_2.1.0, with the one flaw test/vda5050_master.py names).

Measured, over --seconds wall seconds after the trucks' first states:
- ratio: simulated s per wall s achieved (the time factor asked is the most it can be);
- CPU s per simulated s: of the first process (the trucks it steps, the contacts, the bridges
  and links, and the bench's master and checker threads) and of the busiest other process
  (/proc/PID/stat): a process on a core of its own keeps up with real time while its figure
  is below 1;
- state gap: the longest simulated time between two states of one truck (<= 30 s asked),
  from the simulator's tap; states: all states published;
- invalid: messages failing their schema, of all messages received;
- transfers: the dispatcher's transfers done; load: the 1-minute load average at the end
  (the machine's other work: the figures are of this machine at that time).

Run: .venv/bin/python bench/fleet_sim_bench.py [--rows 16:1 32:0.5] [--seconds 120]
     [--processes 2]
Prints a Markdown table (bench/results/fleet_sim_bench.md).
"""

from __future__ import annotations

import argparse
from collections import defaultdict
import json
import os
from pathlib import Path
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from typing import Any

from jsonschema.validators import validator_for
from paho.mqtt.client import Client, MQTTv311
from paho.mqtt.enums import CallbackAPIVersion

from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.fleet_sim import FleetSim
from agv_nodes.fleet.fleet_sim_options import SimOptions, floor_file
from agv_nodes.fleet.mqtt_master import MqttMaster
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.world.fleet_floor import programme_loads
from agv_nodes.world.layout import layout_path, load_layout

TEST = Path(__file__).resolve().parent.parent / 'test'
SCHEMAS = TEST / 'data' / 'vda5050_2.1.0'
sys.path.insert(0, str(TEST))
from vda5050_master import SCHEMA_FLAWS  # noqa: E402 - the schema's flaw, named once

FROM_TRUCK = ('state', 'connection', 'factsheet', 'visualization')


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def mosquitto(tmp: Path) -> tuple[subprocess.Popen, str]:
    """Start a mosquitto of the bench's own; return it and its URL."""
    port = _free_port()
    conf = tmp / 'mosquitto.conf'
    conf.write_text(f'listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n'
                    'max_queued_messages 100000\n')
    exe = shutil.which('mosquitto', path=f'{os.environ.get("PATH", "")}:/usr/sbin')
    if not exe:
        raise SystemExit('mosquitto is not installed (the Debian package mosquitto)')
    process = subprocess.Popen([exe, '-c', str(conf)], cwd=tmp, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    for _ in range(200):
        try:
            socket.create_connection(('127.0.0.1', port), timeout=1.0).close()
            return process, f'mqtt://127.0.0.1:{port}'
        except OSError:
            time.sleep(0.05)
    raise SystemExit(f'mosquitto did not listen on {port}')


class Checker:
    """Every message from a truck, checked against its schema."""

    def __init__(self, url: str) -> None:
        self.validators = {}
        for name in FROM_TRUCK:
            schema = json.loads((SCHEMAS / f'{name}.schema').read_text(encoding='utf-8'))
            self.validators[name] = validator_for(schema)(schema)
        self.counts: dict[str, int] = defaultdict(int)
        self.invalid: list[str] = []
        host, port = url.removeprefix('mqtt://').rsplit(':', 1)
        self.client = Client(callback_api_version=CallbackAPIVersion.VERSION2,
                             client_id='bench_checker', protocol=MQTTv311)
        self.client.on_message = self._on_message
        self.client.connect(host, int(port))
        self.client.subscribe('uagv/v2/+/+/+', 1)
        self.client.loop_start()

    def _on_message(self, _c: Any, _u: Any, message: Any) -> None:
        name = message.topic.rsplit('/', 1)[1]
        if name not in self.validators:
            return
        self.counts[name] += 1
        doc = json.loads(message.payload)
        for e in self.validators[name].iter_errors(doc):
            text = f'{name}: {"/".join(map(str, e.path))}: {e.message}'
            if not any(flaw.match(text.partition(': ')[2]) for flaw in SCHEMA_FLAWS):
                self.invalid.append(text)

    def close(self) -> None:
        """Disconnect."""
        self.client.disconnect()
        self.client.loop_stop()


def cpu_of(pid: int) -> float:
    """Return the CPU seconds (user + system) process `pid` has used so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rpartition(')')[2].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def run(trucks: int, factor: float, seconds: float, processes: int, tmp: Path
        ) -> dict[str, Any]:
    """Run one row; return its figures."""
    name = f'fleet_1983_n{trucks}'
    layout = floor_file(name)
    lay = load_layout(layout_path(layout))
    serials = tuple(f'agv{k + 1}' for k in range(trucks))
    places = dict(zip(serials, lay.parking[:trucks], strict=True))
    broker, url = mosquitto(tmp)
    options = SimOptions(layout=layout, serials=serials, starts=tuple(places.values()),
                         time_factor=factor, processes=processes, status_period=10.0)
    sim = FleetSim(options, url, log=lambda line: print(line, file=sys.stderr, flush=True))
    states: dict[str, list[float]] = defaultdict(list)
    sim.taps.append(lambda truck, topic, _m, now: states[truck].append(now)
                    if topic == 'state' else None)
    checker = Checker(url)
    graph = track_graph(lay)
    dispatcher = Dispatcher(graph, list(serials), positions=places, parking=places)
    loads = programme_loads(lay.stations, trucks)
    where = dict.fromkeys(loads, 0)
    pending: dict[str, str] = {}
    master = MqttMaster(dispatcher, MqttLink(url, 'bench_master'))
    master.link.connect()
    stop = threading.Event()

    def submit(load: str) -> None:
        tid = f't{len(pending) + 1}'
        pending[tid] = load
        dispatcher.submit(TransportOrder(tid, loads[load][where[load]],
                                         loads[load][1 - where[load]]))

    def drive() -> None:
        done = 0
        while not stop.is_set():
            master.step(sim.now)
            while done < len(dispatcher.done):
                load = pending[dispatcher.done[done]]
                where[load] = 1 - where[load]
                done += 1
                submit(load)
            time.sleep(0.1)

    for load in loads:
        submit(load)
    runner = threading.Thread(target=sim.run)
    driver = threading.Thread(target=drive)
    try:
        sim.start()
        runner.start()
        driver.start()
        time.sleep(5.0)  # the first states, the first orders
        pids = [w._process.pid for w in sim.fleet._workers]  # bench only: their CPU
        sim0, wall0, cpu0 = sim.now, time.monotonic(), time.process_time()
        others0 = [cpu_of(pid) for pid in pids]
        time.sleep(seconds)
        sim1, wall1, cpu1 = sim.now, time.monotonic(), time.process_time()
        others = [cpu_of(pid) - c for pid, c in zip(pids, others0, strict=True)]
    finally:
        stop.set()
        sim.quit.set()
        runner.join(60)
        driver.join(10)
        sim.close()
        master.link.close()
        checker.close()
        broker.terminate()
        broker.wait(10)
    gaps = [b - a for t in states.values() for a, b in zip(t, t[1:], strict=False)]
    return {'trucks': trucks, 'factor': factor, 'processes': processes,
            'ratio': (sim1 - sim0) / (wall1 - wall0), 'cpu': (cpu1 - cpu0) / (sim1 - sim0),
            'others': max(others, default=0.0) / (sim1 - sim0),
            'sim': sim1 - sim0, 'states': sum(map(len, states.values())),
            'gap': max(gaps, default=float('nan')), 'messages': sum(checker.counts.values()),
            'invalid': len(checker.invalid), 'first_invalid': checker.invalid[:1],
            'transfers': len(dispatcher.done), 'failed': len(dispatcher.failed),
            'collisions': len(sim.fleet.collisions), 'load': os.getloadavg()[0]}


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rows', nargs='+', default=['16:1', '32:0.5'], metavar='N:FACTOR')
    ap.add_argument('--seconds', type=float, default=120.0, help='wall s measured per row')
    ap.add_argument('--processes', type=int, default=2)
    args = ap.parse_args()
    print('| trucks | time factor asked | processes | ratio achieved | simulated s | '
          'CPU s per sim s: first process | busiest other | states | '
          'longest state gap (sim s) | messages | invalid | transfers | failed | collisions | '
          'load average |')
    print('|' + '---|' * 15)
    with tempfile.TemporaryDirectory() as tmp:
        for spec in args.rows:
            n, _, factor = spec.partition(':')
            r = run(int(n), float(factor), args.seconds, args.processes, Path(tmp))
            print(f'| {r["trucks"]} | {r["factor"]:g} | {r["processes"]} | {r["ratio"]:.2f} | '
                  f'{r["sim"]:.0f} | {r["cpu"]:.2f} | {r["others"]:.2f} | {r["states"]} | '
                  f'{r["gap"]:.1f} | '
                  f'{r["messages"]} | {r["invalid"]} | {r["transfers"]} | {r["failed"]} | '
                  f'{r["collisions"]} | {r["load"]:.1f} |', flush=True)
            if r['first_invalid']:
                print(f'first invalid: {r["first_invalid"][0]}', flush=True)


if __name__ == '__main__':
    main()
