"""agv-fleet-sim trucks report their whole state, read from their own records, to a master.

As test/test_fleet_sim.py: mosquitto of our own, the simulator in a thread as fast as it goes,
the independent master test/vda5050_master.py checking every message against the standard's
JSON schemas. Two trucks in two processes, so one truck's records come from the process that
steps it (agv_nodes.fleet.fleet_sim_records) and the other's from the first process.

Expected values come from outside the simulator: the layout's nodes (fleet_1983: agv2 starts
at W3.1, station A1 holds a load, W1 is empty; `agv-layout graph fleet_1983`), the order sent
(a pick at A1.1, whose conveyor is the first, a drop at W1.1), the standard's enums (6.10.6:
eStop NONE and REMOTE), the world's ground truth of the reference point in `visualization`,
and the fault table's bound for a stop (docs/faults.md: at rest within 5 s).
"""

from __future__ import annotations

from collections.abc import Iterator
import math
from pathlib import Path
import sys
from typing import Any

import pytest
import yaml

from agv_nodes.fleet import fleet_sim_records as records
from agv_nodes.fleet.fleet_sim import SLICE, FleetSim
from agv_nodes.fleet.fleet_sim_options import start_of
from agv_nodes.fleet.fleet_sim_truck import TruckFace
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.harness import truck
from agv_nodes.vda5050.truck_records import RECORDS
from agv_nodes.world.layout import layout_path, load_layout

sys.path.insert(0, str(Path(__file__).parent))
from test_fleet_sim import (  # noqa: E402 - the simulator's fixtures, one place
    AT_REST,
    CRUISE,
    REST_WITHIN,
    WALL,
    Tap,
    _marker_xy,
    _running,
    _wait,
    broker,  # noqa: F401 - a fixture
)
from vda5050_master import Master, action, path  # noqa: E402 - a helper module beside the tests

pytestmark = pytest.mark.timeout(300)

STARTS = {'agv1': 'B3.1', 'agv2': 'W3.1'}  # fleet_1983 stop markers off each other's way
# W3.1 -> A1 -> A1.1 (pick: station A1's load) -> along A -> L1 -> W1.1 (drop: station W1)
DELIVERY = ['W3.1', 'A1', 'A1.1', 'A2', 'A2.1', 'A3', 'A3.1', 'A4', 'A4.1', 'A5', 'A5.1', 'A6',
            'A6.1', 'A7', 'A7.1', 'A8', 'A8.1', 'L1', 'W1.1']
STATE_INTERVAL = 1.0  # s: a state every simulated second, so some fall between markers
AT_NODE = 0.005  # m: initPosition places agvPosition at the node itself (the truck at rest)
BETWEEN = 1.0  # m from the last node read: a position between markers
WAYS = {'agv1': ['B3.1', 'B4', 'B4.1', 'B5', 'B5.1', 'B6', 'B6.1', 'B7', 'B7.1', 'B8', 'B8.1'],
        'agv2': DELIVERY}


@pytest.fixture
def pair(broker) -> Iterator[tuple[FleetSim, Tap, str]]:  # noqa: F811 - the fixture above
    """agv1 in the first process, agv2 in the second; a visualization every slice."""
    yield from _running(broker, tuple(STARTS), tuple(STARTS.values()), 2,
                        visualization_period=SLICE, state_interval=STATE_INTERVAL)


def _master(url: str, truck: str) -> Master:
    m = Master(url, 'agv_nodes', truck)
    m.instant({'actionType': 'stateRequest', 'actionId': 'hello', 'blockingType': 'NONE',
               'actionParameters': []})
    m.wait_for('state', lambda s: s['lastNodeId'] == STARTS[truck], WALL,
               f'lastNodeId {STARTS[truck]}')
    return m


def _action(state: dict, action_id: str) -> str:
    return next((a['actionStatus'] for a in state['actionStates']
                 if a['actionId'] == action_id), '')


def _sim_time(tap: Tap, truck: str, name: str, message: dict) -> float:
    """Return the simulated time the simulator published `message` (by its headerId)."""
    return next(t for t, m in tap.of(truck, name) if m['headerId'] == message['headerId'])


def test_loads_and_position_follow_a_delivery(pair):
    sim, tap, url = pair
    master = _master(url, 'agv2')
    try:
        # initPosition at the start: the truck knows where it stands, at the node itself
        first = master.states()[0]['agvPosition']
        assert first['positionInitialized'] is True
        assert math.dist((first['x'], first['y']), _marker_xy('W3.1')) < AT_NODE, first
        nodes, edges = path(DELIVERY, actions={'A1.1': [action('pick', 'pick-A1.1')],
                                               'W1.1': [action('drop', 'drop-W1.1')]})
        master.order('delivery', 0, nodes, edges)
        done = master.wait_for('state', lambda s: _action(s, 'drop-W1.1') == 'FINISHED'
                               and not s['driving'], WALL * 2, 'the drop finished')
        assert done['errors'] == [] and done['lastNodeId'] == 'W1.1'
    finally:
        master.close()
    assert master.invalid == [], master.invalid[:5]
    states = master.states()
    order = [s for s in states if s['orderId'] == 'delivery']
    # loads: none until the pick, the first conveyor's after it, none after the drop
    before = [s.get('loads') for s in order if _action(s, 'pick-A1.1') in ('WAITING', '')]
    carrying = [s.get('loads') for s in order if _action(s, 'pick-A1.1') == 'FINISHED'
                and _action(s, 'drop-W1.1') == 'WAITING']
    after = [s.get('loads') for s in order if _action(s, 'drop-W1.1') == 'FINISHED']
    assert before and all(loads == [] for loads in before), before
    assert carrying and all(loads == [{'loadPosition': 'first'}] for loads in carrying), carrying
    assert after and all(loads == [] for loads in after), after
    # agvPosition: dead reckoning since the last node, within the deviationRange it claims of
    # the world's reference point (the visualization of the same slice)
    truth = {t: v['agvPosition'] for t, v in tap.of('agv2', 'visualization')}
    paired = between = 0
    for s in order:
        p = s['agvPosition']
        assert p['positionInitialized'] is True, s
        t = _sim_time(tap, 'agv2', 'state', s)
        if t not in truth:
            continue
        paired += 1
        error = math.dist((p['x'], p['y']), (truth[t]['x'], truth[t]['y']))
        assert error <= p['deviationRange'], (t, error, p, truth[t])
        if math.dist((p['x'], p['y']), _marker_xy(s['lastNodeId'])) > BETWEEN:
            between += 1
            assert s['distanceSinceLastNode'] > 0, s  # driven since, by the wheel counters
    assert paired >= len(order) // 2, (paired, len(order))
    assert between >= 5, between  # 11 m from A8.1 to L1 alone: states a second apart


@pytest.mark.parametrize('truck', ['agv1', 'agv2'])
def test_a_radio_stop_is_a_remote_e_stop_at_rest_and_clears(pair, truck):
    sim, tap, url = pair
    master = _master(url, truck)
    try:
        nodes, edges = path(WAYS[truck])
        master.order('far', 0, nodes, edges)
        _wait(lambda: any(v['velocity']['vx'] > CRUISE
                          for _t, v in tap.of(truck, 'visualization')), f'{truck} cruising')
        assert all(s['safetyState']['eStop'] == 'NONE' for s in master.states())
        sim.command(f'fault {truck} radioStop')
        _wait(lambda: any(c == f'fault {truck} radioStop' for _t, c, _w in sim.results),
              'the fault')
        at = next(t for t, c, _w in sim.results if c == f'fault {truck} radioStop')
        stopped = master.wait_for(
            'state', lambda s: s['safetyState']['eStop'] == 'REMOTE' and
            _sim_time(tap, truck, 'state', s) >= at + REST_WITHIN, WALL, 'eStop REMOTE at rest')
        assert abs(stopped['velocity']['vx']) < AT_REST and not stopped['driving'], stopped
        assert stopped['safetyState']['fieldViolation'] is False
        sim.command(f'clear {truck} radioStop')
        master.wait_for('state', lambda s: s['safetyState']['eStop'] == 'NONE' and
                        _sim_time(tap, truck, 'state', s) > at + REST_WITHIN, WALL,
                        'eStop NONE after the clear')
    finally:
        master.close()
    assert master.invalid == [], master.invalid[:5]
    # once REMOTE, every state said so until the clear
    cleared = next(t for t, c, _w in sim.results if c == f'clear {truck} radioStop')
    since = [(t, m['safetyState']['eStop']) for t, m in tap.of(truck, 'state')
             if at <= t <= cleared]
    first = next(i for i, (_t, e) in enumerate(since) if e == 'REMOTE')
    assert {e for _t, e in since[first:]} == {'REMOTE'}, since
    assert since[first][0] - at < REST_WITHIN, since[:first + 1]


# --- the taps without a broker: one round trip per process, bad records counted -------------

def _schema(record: str) -> dict:
    return yaml.safe_load((Path(__file__).parent.parent / 'msg_schemas' / f'{record}.yaml')
                          .read_text(encoding='utf-8'))


@pytest.mark.timeout(120)
def test_each_process_hands_over_its_trucks_records_in_one_round_trip():
    lay = load_layout(layout_path('fleet_1983'))
    names = ['agv1', 'agv2', 'agv3']
    with Fleet('fleet_1983', [start_of(lay, m) for m in ('A1.1', 'B1.1', 'B5.1')], seed=1,
               names=names, processes=2) as fleet:
        for name in names:
            fleet.query(name, records.tap, 'sim', name)
            fleet.query(name, records.tap, 'other', name)  # another simulator's, apart
        asked: list[str] = []

        def query(name: str, fn: Any, *args: Any) -> Any:
            asked.append(name)
            return fleet.query(name, fn, *args)

        fleet.run(1.0)
        got = records.take_all(query, names, 'sim')
        assert len(asked) == 2, asked  # one per process
        assert sorted(got) == names
        period = _schema('wheel_odometry')['period_ms'] / 1000.0
        for name in names:
            assert {r for r, _raw, _t in got[name]} <= set(RECORDS)
            wheels = [t for r, _raw, t in got[name] if r == 'wheel_odometry']
            # every one the truck wrote in the second, none twice (msg_schemas period)
            assert abs(len(wheels) - fleet.now / period) <= 1, (name, len(wheels))
            assert len(set(wheels)) == len(wheels)
        assert all(kept == [] for kept in records.take_all(fleet.query, names, 'sim').values())
        # the other simulator's taps kept their own copy
        assert all(got[n] == kept for n, kept in
                   records.take_all(fleet.query, names, 'other').items())
        fleet.query('agv2', records.untap, 'sim', 'agv2')
        fleet.run(0.1)
        assert sorted(records.take_all(fleet.query, names, 'sim')) == ['agv1', 'agv3']
        records.forget('sim')
        records.forget('other')


@pytest.mark.timeout(60)
def test_a_corrupted_record_is_counted_and_not_acted_on():
    h = truck('fleet_1983', start=None)
    kept: list[tuple[str, bytes, float]] = []
    h.taps.append(lambda record, raw, t: kept.append((record, raw, t)))
    h.run(0.2)
    face = TruckFace('agv1', 'mqtt://127.0.0.1:1', track_graph(load_layout(
        layout_path('fleet_1983'))), manufacturer='agv_nodes', interface='uagv',
        map_id='fleet_1983', state_interval=30.0)
    loads = [(r, raw, t) for r, raw, t in kept if r == 'load_status']
    face.read(loads[:1], 0.0)
    assert face.bridge.state().loads == []  # the conveyors empty, as the world has them
    # load_first: byte 3 bit 0 (msg_schemas/load_status.yaml), set without a new CRC
    bit = next(f for f in _schema('load_status')['fields'] if f['name'] == 'load_first')
    record, raw, t = loads[1]
    bad = bytearray(raw)
    bad[bit['byte']] ^= 1 << int(str(bit['bits']).split('-')[0])
    out = face.read([(record, bytes(bad), t)], 0.05)
    assert face.records.readers['load_status'].rejected == 1
    assert out.messages == [] and face.bridge.state().loads == []
