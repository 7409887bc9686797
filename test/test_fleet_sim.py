"""agv-fleet-sim on a real broker (mosquitto): masters written apart drive its trucks.

The master is test/vda5050_master.py (plain paho, hand-written JSON, every message from a truck
checked against the standard's JSON schemas in test/data/vda5050_2.1.0). The simulator runs
in a thread as fast as it goes (time factor 0); what is bounded is bounded in simulated time,
read from the simulator's tap on what each truck publishes, and every wall-clock wait is a
limit on an event, never a pause that must be long enough.

Expected values come from outside the simulator: the layout's stop markers (fleet_1983), the
standard's connection states (6.14), and the fault table's bound for a fault while cruising,
at rest within 5 s (docs/faults.md, the DDS fault tests).
"""

from __future__ import annotations

from collections.abc import Iterator
import json
import math
import os
from pathlib import Path
import shutil
import socket
import subprocess
import sys
import threading
import time
from typing import Any

from paho.mqtt.client import Client, MQTTv311
from paho.mqtt.enums import CallbackAPIVersion
import pytest

from agv_nodes.fleet.fleet_sim import SLICE, FleetSim
from agv_nodes.fleet.fleet_sim_control import CommandError, from_json, from_line
from agv_nodes.fleet.fleet_sim_options import SimOptions

sys.path.insert(0, str(Path(__file__).parent))
from vda5050_master import Master, path  # noqa: E402 - a helper module beside the tests

pytestmark = pytest.mark.timeout(240)

WALL = 120.0  # wall s any one awaited message may take on a loaded machine
AT_REST = 0.01  # m/s
STOP_WITHIN = 0.01  # m: a stop at a marker (docs/tasks.md: stops within a few mm)
STATE_INTERVAL = 5.0  # s: the trucks' state_interval here, to see two in a short run
REST_WITHIN = 5.0  # simulated s from a fault to the truck at rest (docs/faults.md)
CRUISE = 0.3  # m/s: the truck is under way when the fault comes
TRUCKS = ('agv1', 'agv2', 'agv3')
STARTS = ('A1.1', 'B1.1', 'B5.1')  # fleet_1983 stop markers, apart


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@pytest.fixture
def broker(tmp_path) -> Iterator[str]:
    """Run a mosquitto of our own on a free port."""
    port = _free_port()
    conf = tmp_path / 'mosquitto.conf'
    conf.write_text(f'listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n')
    executable = shutil.which('mosquitto', path=f'{os.environ.get("PATH", "")}:/usr/sbin')
    assert executable, 'mosquitto is not installed (the Debian package mosquitto)'
    process = subprocess.Popen([executable, '-c', str(conf)], cwd=tmp_path,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 10
        while True:
            try:
                socket.create_connection(('127.0.0.1', port), timeout=1.0).close()
                break
            except OSError:
                assert time.monotonic() < deadline and process.poll() is None, \
                    f'mosquitto did not listen on {port}'
                time.sleep(0.05)
        yield f'mqtt://127.0.0.1:{port}'
    finally:
        process.terminate()
        process.wait(10)


class Tap:
    """What the trucks published, with the simulated time of each (the simulator's tap)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.seen: list[tuple[float, str, str, dict]] = []

    def __call__(self, truck: str, name: str, message: Any, now: float) -> None:
        with self.lock:
            self.seen.append((now, truck, name, message.model_dump(by_alias=True)))

    def of(self, truck: str, name: str) -> list[tuple[float, dict]]:
        with self.lock:
            return [(t, m) for t, tr, n, m in self.seen if tr == truck and n == name]


def _running(url: str, serials: tuple[str, ...], starts: tuple[str, ...], processes: int,
             **settings: Any) -> Iterator[tuple[FleetSim, Tap, str]]:
    options = SimOptions(layout='fleet_1983', serials=serials, starts=starts, time_factor=0.0,
                         processes=processes, **{'visualization_period': 0.1,
                                                 'status_period': 2.0,
                                                 'state_interval': STATE_INTERVAL, **settings})
    lines: list[str] = []
    sim = FleetSim(options, url, log=lines.append)
    tap = Tap()
    sim.taps.append(tap)
    runner = threading.Thread(target=sim.run, daemon=True)
    try:
        sim.start()
        runner.start()
        yield sim, tap, url
    finally:
        sim.quit.set()
        runner.join(30)
        sim.close()
    assert not runner.is_alive()


@pytest.fixture
def fleet_sim(broker) -> Iterator[tuple[FleetSim, Tap, str]]:
    """Three trucks on fleet_1983 in one process, running in a thread until the test ends."""
    yield from _running(broker, TRUCKS, STARTS, 1)


@pytest.fixture
def two_processes(broker) -> Iterator[tuple[FleetSim, Tap, str]]:
    """Two trucks on fleet_1983 in two processes: a truck added goes to the second."""
    yield from _running(broker, TRUCKS[:2], STARTS[:2], 2)


@pytest.fixture
def master(fleet_sim) -> Iterator[Master]:
    """Give the independent master of agv1, once agv1's first state has named its start."""
    m = Master(fleet_sim[2], 'agv_nodes', 'agv1')
    try:
        m.instant({'actionType': 'stateRequest', 'actionId': 'hello', 'blockingType': 'NONE',
                   'actionParameters': []})
        m.wait_for('state', lambda s: s['lastNodeId'] == 'A1.1', WALL, 'lastNodeId A1.1')
        yield m
    finally:
        m.close()
    assert m.invalid == [], m.invalid[:5]


def _idle(node: str, order_id: str) -> Any:
    return lambda s: (s['orderId'] == order_id and s['lastNodeId'] == node
                      and not s['nodeStates'] and not s['edgeStates'] and not s['driving'])


def test_a_master_drives_a_truck_to_the_end_of_its_order(fleet_sim, master):
    sim, tap, _url = fleet_sim
    nodes, edges = path(['A1.1', 'A2', 'A2.1', 'A3', 'A3.1'])
    master.order('o1', 0, nodes, edges)
    done = master.wait_for('state', _idle('A3.1', 'o1'), WALL, 'order o1 done at A3.1')
    assert done['errors'] == []
    # the truck is where the layout has A3.1, at rest: its visualization from the world
    # (the reference point: the front axle centre, where the marker sensor reads the card)
    x, y = _marker_xy('A3.1')
    now, vis = tap.of('agv1', 'visualization')[-1]
    p = vis['agvPosition']
    assert abs(vis['velocity']['vx']) < AT_REST
    assert math.dist((p['x'], p['y']), (x, y)) < STOP_WITHIN, (p, x, y)
    assert master.received['factsheet'] and master.received['connection'][0][
        'connectionState'] == 'ONLINE'
    # the others stood still: nothing was sent to them
    for truck in ('agv2', 'agv3'):
        assert all(abs(v['velocity']['vx']) < AT_REST for _t, v in tap.of(truck, 'visualization'))


def _marker_xy(name: str) -> tuple[float, float]:
    from agv_nodes.world.layout import layout_path, load_layout
    lay = load_layout(layout_path('fleet_1983'))
    marker = next(m for m in lay.markers if m.name == name)
    return lay.paths[marker.path].pose_at(marker.at)[:2]


def test_states_come_at_least_every_state_interval_and_on_each_change(fleet_sim, master):
    sim, tap, _url = fleet_sim
    nodes, edges = path(['A1.1', 'A2', 'A2.1'])
    master.order('o2', 0, nodes, edges)
    master.wait_for('state', _idle('A2.1', 'o2'), WALL, 'order o2 done')
    until = sim.now + 2 * sim.o.state_interval + 1
    deadline = time.monotonic() + WALL
    while sim.now < until:
        assert time.monotonic() < deadline, 'the simulator stalled'
        time.sleep(0.1)
    for truck in TRUCKS:
        times = [t for t, _s in tap.of(truck, 'state')]
        gaps = [b - a for a, b in zip(times, times[1:], strict=False)]
        assert max(gaps) <= STATE_INTERVAL + SLICE + 1e-9, (truck, max(gaps))
    # each node passed was a change, sent as a state of its own (6.10)
    passed = [s['lastNodeId'] for s in master.states() if s['orderId'] == 'o2']
    assert [n for i, n in enumerate(passed) if not i or passed[i - 1] != n] == \
        ['A1.1', 'A2', 'A2.1']


def test_a_cut_broker_link_shows_the_last_will_and_mends(fleet_sim, master):
    sim, tap, url = fleet_sim
    watcher = Master(url, 'agv_nodes', 'agv2')
    try:
        watcher.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE', WALL,
                         'agv2 ONLINE')
        sim.command('fault agv2 brokerLink')
        watcher.wait_for('connection', lambda c: c['connectionState'] == 'CONNECTIONBROKEN',
                         WALL, "agv2's last will")
        sim.command('clear agv2 brokerLink')
        watcher.wait_for('state', lambda s: any(i['infoType'] == 'brokerConnectionGap'
                                                for i in s.get('information', [])),
                         WALL, 'the gap reported after the link is back')
        assert watcher.received['connection'][-1]['connectionState'] == 'ONLINE'
    finally:
        watcher.close()
    assert watcher.invalid == []


def _control(url: str) -> tuple[Client, list[dict]]:
    statuses: list[dict] = []
    host, port = url.removeprefix('mqtt://').rsplit(':', 1)
    client = Client(callback_api_version=CallbackAPIVersion.VERSION2, client_id='tester',
                    protocol=MQTTv311)
    client.on_message = lambda _c, _u, m: statuses.append(json.loads(m.payload))
    client.connect(host, int(port))
    client.subscribe('uagv/v2/agv_nodes/fleet-sim/status', 1)
    client.loop_start()
    return client, statuses


def _wait(condition: Any, what: str) -> None:
    deadline = time.monotonic() + WALL
    while not condition():
        assert time.monotonic() < deadline, f'no {what} within {WALL:g} s'
        time.sleep(0.05)


def test_a_truck_is_added_and_removed_over_the_control_topic(two_processes):
    sim, tap, url = two_processes
    master = Master(url, 'agv_nodes', 'agv1')
    client, statuses = _control(url)
    new = Master(url, 'agv_nodes', 'agv9')
    try:
        topic = 'uagv/v2/agv_nodes/fleet-sim/control'
        client.publish(topic, '{"command": "add", "serialNumber": "agv9", "start": "A5.1"}',
                       qos=1).wait_for_publish(5)
        new.wait_for('state', lambda s: s['lastNodeId'] == 'A5.1', WALL, 'agv9 at A5.1')
        # one truck in each process: the added one goes to the second (Fleet.add)
        assert sim.fleet._owner.get('agv9') is sim.fleet._workers[0]
        assert new.received['factsheet'], 'no factsheet from the added truck'
        # the new truck drives: an order to the next stop
        nodes, edges = path(['A5.1', 'A6', 'A6.1'])
        new.order('n1', 0, nodes, edges)
        new.wait_for('state', _idle('A6.1', 'n1'), WALL, 'agv9 done at A6.1')
        # bad commands: rejected, counted, nothing done
        for bad in ('{"command": "add", "serialNumber": "agv9", "start": "A7.1"}',
                    '{"command": "fault", "serialNumber": "agv1", "fault": "fire"}', 'nonsense'):
            client.publish(topic, bad, qos=1).wait_for_publish(5)
        _wait(lambda: statuses and statuses[-1]['rejected'] == 3, 'three rejections counted')
        assert 'fire' not in json.dumps(statuses[-1]['faults'])
        assert sorted(statuses[-1]['trucks']) == ['agv1', 'agv2', 'agv9']
        client.publish(topic, '{"command": "remove", "serialNumber": "agv9"}',
                       qos=1).wait_for_publish(5)
        new.wait_for('connection', lambda c: c['connectionState'] == 'OFFLINE', WALL,
                     'agv9 OFFLINE')
        _wait(lambda: statuses and 'agv9' not in statuses[-1]['trucks'], 'agv9 gone')
        # the others go on: agv1 still answers its master
        nodes, edges = path(['A1.1', 'A2', 'A2.1'])
        master.order('o3', 0, nodes, edges)
        master.wait_for('state', _idle('A2.1', 'o3'), WALL, 'agv1 done after the removal')
    finally:
        new.close()
        master.close()
        client.loop_stop()
        client.disconnect()
    assert new.invalid == [] and master.invalid == []
    assert sim.fleet._owner.get('agv9') is None and len(sim.fleet._workers) == 1
    assert [why for _t, _c, why in sim.results].count('ok') == 2


@pytest.mark.parametrize(('fault', 'cause'), [
    ('drive', 'FAILED: tripped (traction)'),  # the trip relay opened (docs/faults.md)
    ('radioStop', 'FAILED: radio stop (traction)')])
def test_a_fault_while_cruising_stops_the_truck_with_an_error_in_its_state(fleet_sim, master,
                                                                          fault, cause):
    sim, tap, _url = fleet_sim
    nodes, edges = path(['A1.1', 'A2', 'A2.1', 'A3', 'A3.1', 'A4', 'A4.1', 'A5', 'A5.1'])
    master.order('far', 0, nodes, edges)
    _wait(lambda: any(v['velocity']['vx'] > CRUISE for _t, v in tap.of('agv1', 'visualization')),
          'agv1 cruising')
    sim.command(f'fault agv1 {fault}')
    _wait(lambda: any(c == f'fault agv1 {fault}' for _t, c, _w in sim.results), 'the fault')
    at = next(t for t, c, _w in sim.results if c == f'fault agv1 {fault}')
    failed = master.wait_for('state', lambda s: s['errors'] and not s['driving'], WALL,
                             'an error, not driving')
    assert failed['orderId'] == 'far'
    assert [(e['errorType'], cause in e['errorDescription']) for e in failed['errors']] == \
        [('taskFailed', True)], failed['errors']
    _wait(lambda: sim.now > at + REST_WITHIN + 2.0, 'simulated time past the bound')
    after = [(t, v['velocity']['vx']) for t, v in tap.of('agv1', 'visualization')
             if t >= at + REST_WITHIN]
    assert after and all(abs(vx) < AT_REST for _t, vx in after), after[:5]
    # and it stays where it stopped: no new order, no drive
    xs = [v['agvPosition']['x'] for t, v in tap.of('agv1', 'visualization')
          if t >= at + REST_WITHIN]
    assert max(xs) - min(xs) < 0.005


def test_a_blocked_stop_marker_ends_at_the_positioning_limit_with_an_error(fleet_sim, master):
    sim, tap, _url = fleet_sim
    sim.command('fault agv1 blockedMarker A2.1')
    _wait(lambda: any(c == 'fault agv1 blockedMarker A2.1' for _t, c, _w in sim.results),
          'the fault taken')
    nodes, edges = path(['A1.1', 'A2', 'A2.1'])
    master.order('blind', 0, nodes, edges)
    failed = master.wait_for('state', lambda s: s['errors'] and not s['driving'], WALL,
                             'an error, not driving')
    assert [(e['errorType'], 'FAILED: route limit (navigation)' in e['errorDescription'])
            for e in failed['errors']] == [('taskFailed', True)], failed['errors']
    assert failed['lastNodeId'] == 'A2'  # the location read; the covered stop never
    # at rest past the covered card, within the executive's positioning_limit of it
    # (agv_nodes/executive/parameters.yaml: 4.0 m from where positioning starts, before it)
    limit = 4.0
    _wait(lambda: (tap.of('agv1', 'visualization')[-1][0] > sim.now - 1.0
                   and abs(tap.of('agv1', 'visualization')[-1][1]['velocity']['vx']) < AT_REST),
          'agv1 at rest')
    p = tap.of('agv1', 'visualization')[-1][1]['agvPosition']  # the sensor's point
    x, _y = _marker_xy('A2.1')
    assert x < p['x'] < x + limit, (p['x'], x)


@pytest.mark.parametrize(('line', 'problem'), [
    ('fault agv1 fire', "fault 'fire' is not one of"),
    ('fault agv1 blockedMarker', 'a marker goes with blockedMarker'),
    ('add agv9', 'expected one of'),
    ('launch', "unknown command 'launch'"),
    ('', 'empty'),
])
def test_a_bad_command_line_says_what_is_wrong(line, problem):
    with pytest.raises(CommandError) as raised:
        from_line(line)
    assert problem in str(raised.value) and '\n' not in str(raised.value)


@pytest.mark.parametrize(('payload', 'problem'), [
    ('{"command": "remove"', 'not JSON'),
    ('["remove"]', 'not a JSON object'),
    ('{"command": "remove", "serialNumber": 7}', "'serialNumber' must be a string"),
    ('{"command": "remove", "serialNumber": "agv1", "truck": "x"}', "unknown key 'truck'"),
    ('{"command": "status", "serialNumber": "agv1"}', 'status takes nothing more'),
])
def test_a_bad_control_message_says_what_is_wrong(payload, problem):
    with pytest.raises(CommandError) as raised:
        from_json(payload)
    assert problem in str(raised.value) and '\n' not in str(raised.value)


@pytest.mark.parametrize(('args', 'problem'), [
    (['--trucks', '0'], '--trucks 0: give 1 or more'),
    (['--trucks', '9'], '--trucks 9: layout fleet_1983 parks 8'),
    (['--trucks', '2', '--starts', 'A1.1,X'], "'X' is no stop marker of fleet_1983"),
    (['--state-interval', '31'], '--state-interval 31.0: give more than 0 and at most 30 s'),
    (['--layout', 'tape_1991'], 'the fleet runs on a wire layout'),
])
def test_a_bad_option_stops_in_one_line(args, problem):
    run = subprocess.run([sys.executable, '-m', 'agv_nodes.fleet.fleet_sim', *args],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert run.stderr.startswith('agv-fleet-sim: ') and run.stderr.count('\n') == 1, run.stderr
    assert problem in run.stderr, run.stderr


def test_stdin_commands_reach_the_running_simulator(broker):
    run = subprocess.run([sys.executable, '-m', 'agv_nodes.fleet.fleet_sim', '--mqtt-url',
                          broker, '--trucks', '1', '--time-factor', '0', '--seconds', '3'],
                         input='fault agv1 radioStop\nfault agv1 fire\n', capture_output=True,
                         text=True, timeout=180)
    assert run.returncode == 0, run.stderr
    assert 'fleet-sim: fault agv1 radioStop: ok' in run.stdout, run.stdout
    assert "fleet-sim: rejected 'fault agv1 fire\\n': fault agv1: fault 'fire'" in run.stdout
