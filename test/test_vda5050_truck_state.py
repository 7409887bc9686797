"""The state a master sees, from the truck's own records, against the world's ground truth.

The whole 1983 truck runs in lock step (agv_nodes.harness.truck on demo_1983); its bridge core
gets the records a bridge reads (position_sensor_status, load_status, traction_status,
wheel_odometry), decoded by readers of their own, and communications' report lines, as the
bridge node gets them over DDS. What the state says is held against the world (where the
truck's sensor point is, what its conveyors carry) and the order (which nodes it passes), never
against the bridge's own reckoning. Every state goes out as JSON and must validate against the
official 2.1.0 state schema (test/data/vda5050_2.1.0).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from jsonschema.validators import validator_for
import pytest

from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.harness import submit, truck
from agv_nodes.vda5050.bridge import BridgeCore, Outbox
from agv_nodes.vda5050.codec import to_json
from agv_nodes.vda5050.truck_records import RecordTap
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(600)

SCHEMAS = Path(__file__).parent / 'data' / 'vda5050_2.1.0'
# The order of the outside tester's run: a pick at W0.1, a drop at W2.1, on past W2.2 and L1
# to a stop at W1.1 (demo_1983's loop, docs/vda5050.md).
WAY = ['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'W1.1']


def _validator(name: str) -> Any:
    schema = json.loads((SCHEMAS / f'{name}.schema').read_text(encoding='utf-8'))
    return validator_for(schema)(schema)


def order(ids: list[str], actions: dict[str, str]) -> str:
    """Return an order as a master writes it (6.6), by hand: every node released."""
    nodes = [{'nodeId': n, 'sequenceId': 2 * i, 'released': True,
              'actions': [{'actionType': actions[n], 'actionId': f'{actions[n]}-{n}',
                           'blockingType': 'HARD'}] if n in actions else []}
             for i, n in enumerate(ids)]
    edges = [{'edgeId': f'{a}-{b}', 'sequenceId': 2 * i + 1, 'released': True,
              'startNodeId': a, 'endNodeId': b, 'actions': []}
             for i, (a, b) in enumerate(zip(ids, ids[1:], strict=False))]
    return json.dumps({'headerId': 0, 'timestamp': '2026-01-01T00:00:00.000Z',
                       'version': '2.1.0', 'manufacturer': 'agv_nodes', 'serialNumber': 'agv1',
                       'orderId': 'o1', 'orderUpdateId': 0, 'nodes': nodes, 'edges': edges})


class BridgedTruck:
    """One lock-step truck and its bridge core; every state kept with the ground truth then."""

    def __init__(self, seed: int = 1) -> None:
        self.h = truck('demo_1983', seed=seed)
        self.graph = track_graph(load_layout(layout_path('demo_1983')))
        self.core = BridgeCore(self.graph, 'agv_nodes', 'agv1', map_id='demo_1983',
                               electruk=self.h.world.p.electruk)
        self.tap = RecordTap(self.core)  # the records, each judged by a reader of its own
        self.states: list[dict[str, Any]] = []
        self.truth: list[dict[str, Any]] = []  # the world when each state was sent
        self.messages: list[tuple[str, dict[str, Any]]] = []
        self.positions: list[tuple[dict[str, Any], dict[str, Any]]] = []  # with the truth then
        self._validators = {n: _validator(n) for n in ('state', 'visualization')}
        self.invalid: list[str] = []
        self.h.taps.append(self.tap)

    def truth_now(self) -> dict[str, Any]:
        v = self.h.world.vehicle
        return {'sensor': v.sensor_point, 'heading': v.state.heading, 't': self.h.now,
                'loads': list(self.h.world.conveyors.loads)}

    def apply(self, out: Outbox) -> None:
        for text in out.tasks:
            submit(self.h, text)
        for name, message in out.messages:
            doc = json.loads(to_json(message))
            self.invalid += [f'{name}: {e.message}'
                             for e in self._validators[name].iter_errors(doc)] \
                if name in self._validators else []
            self.messages.append((name, doc))
            if name == 'visualization':
                self.positions.append((doc['agvPosition'], self.truth_now()))
            if name == 'state':
                self.positions.append((doc['agvPosition'], self.truth_now()))
                self.states.append(doc)
                self.truth.append(self.truth_now())

    def step(self) -> None:
        self.h.step()
        now = self.h.now
        self.apply(self.tap.take())
        for note in self.h.cores['communications'].notes.take():
            self.apply(self.core.on_report(note.text, now))
        self.apply(self.core.tick(now))

    def run(self, seconds: float, until: Any = None) -> bool:
        end = self.h.now + seconds
        while self.h.now < end:
            self.step()
            if until is not None and until():
                return True
        return False


@pytest.fixture(scope='module')
def delivery() -> BridgedTruck:
    """Drive the outside tester's order to its end (pick at W0.1, drop at W2.1, stop W1.1)."""
    t = BridgedTruck()
    t.apply(t.core.state_now(0.0))
    t.run(1.0)
    t.apply(t.core.on_message('order', order(WAY, {'W0.1': 'pick', 'W2.1': 'drop'}), t.h.now))
    t.run(400.0, until=lambda: bool(t.states) and not t.states[-1]['nodeStates']
          and all(a['actionStatus'] == 'FINISHED' for a in t.states[-1]['actionStates']))
    return t


def test_every_message_validates_against_the_official_schemas(delivery):
    assert delivery.states and not delivery.invalid


def test_the_order_ends_with_both_actions_finished(delivery):
    last = delivery.states[-1]
    assert {a['actionId']: a['actionStatus'] for a in last['actionStates']} == {
        'pick-W0.1': 'FINISHED', 'drop-W2.1': 'FINISHED'}
    assert last['lastNodeId'] == 'W1.1' and not last['errors']


def test_every_node_passed_becomes_last_node_in_order_stop_markers_included(delivery):
    seen: list[str] = []
    for s in delivery.states:
        if s['lastNodeId'] and (not seen or seen[-1] != s['lastNodeId']):
            seen.append(s['lastNodeId'])
    assert seen == WAY


def test_a_passed_stop_marker_is_last_node_while_the_truck_is_at_it(delivery):
    """W2.2, driven past on the way to L1, is lastNodeId when the sensor is over it."""
    w22 = delivery.graph.nodes['W2.2']
    first = next(i for i, s in enumerate(delivery.states) if s['lastNodeId'] == 'W2.2')
    x, y = delivery.truth[first]['sensor']
    along = (x - w22.x) * math.cos(w22.theta) + (y - w22.y) * math.sin(w22.theta)
    # the stop strip is 200 mm long (Baker 1983, 4.3): its centre is read within it
    assert abs(along) <= 0.1, f'W2.2 became lastNodeId {along:+.3f} m from its card'


def test_last_node_is_not_set_before_the_truck_has_read_the_first_node(delivery):
    """The order is accepted at once; L0 is lastNodeId only once the truck is over it."""
    l0 = delivery.graph.nodes['L0']
    accepted = next(i for i, s in enumerate(delivery.states) if s['orderId'] == 'o1')
    assert delivery.states[accepted]['lastNodeId'] == ''
    assert delivery.states[accepted]['nodeStates'][0]['nodeId'] == 'L0'
    assert delivery.states[accepted]['agvPosition']['positionInitialized'] is False
    first = next(i for i, s in enumerate(delivery.states) if s['lastNodeId'] == 'L0')
    x, y = delivery.truth[first]['sensor']
    assert math.hypot(x - l0.x, y - l0.y) <= 0.1
    assert delivery.truth[first]['t'] > delivery.truth[accepted]['t']
    assert delivery.states[first]['agvPosition']['positionInitialized'] is True


def test_loads_follow_the_conveyors_as_the_world_has_them(delivery):
    """Empty, the pick's load on the first conveyor, empty after the drop: as the world has it."""
    said: list[list[str]] = []
    for s, truth in zip(delivery.states, delivery.truth, strict=True):
        if 'loads' not in s:
            continue  # load handling not heard yet: the truck cannot tell
        carried = sorted(load['loadPosition'] for load in s['loads'])
        if not said or said[-1] != carried:
            said.append(carried)
            world = [n for n, on in zip(('first', 'second'), truth['loads'], strict=True) if on]
            assert carried == world, f'the state says {carried}, the world has {world}'
    assert said == [[], ['first'], []]
    pick = next(s for s in delivery.states
                if {'actionId': 'pick-W0.1', 'actionStatus': 'FINISHED'}.items()
                <= {k: v for a in s['actionStates'] if a['actionId'] == 'pick-W0.1'
                    for k, v in a.items()}.items())
    assert [load['loadPosition'] for load in pick['loads']] == ['first']


def test_agv_position_is_within_its_deviation_range_of_the_ground_truth(delivery):
    """Every position the truck sends (state, visualization) holds the true sensor point."""
    checked = 0
    for p, truth in delivery.positions:
        if not p['positionInitialized']:
            continue
        x, y = truth['sensor']
        error = math.hypot(p['x'] - x, p['y'] - y)
        assert error <= p['deviationRange'], (truth['t'], error, p)
        assert 0.0 < p['localizationScore'] <= 1.0
        checked += 1
    assert checked > 30


def test_the_radio_stop_is_a_remote_e_stop_and_the_truck_stops():
    """The radio stop (hw/radio_stop) mid-drive: eStop REMOTE while the world has it set."""
    t = BridgedTruck(seed=2)
    t.apply(t.core.state_now(0.0))
    t.run(1.0)
    t.apply(t.core.on_message('order', order(WAY[:4], {}), t.h.now))
    assert t.run(60.0, until=lambda: t.h.world.vehicle.state.speed > 0.3)
    t.h.set_radio_stop(True)
    assert t.run(5.0, until=lambda: t.states[-1]['safetyState']['eStop'] == 'REMOTE')
    t.run(5.0)
    assert t.states[-1]['safetyState'] == {'eStop': 'REMOTE', 'fieldViolation': False}
    assert abs(t.h.world.vehicle.state.speed) < 0.01  # the world: the truck stands
    assert not t.states[-1]['driving']
    t.h.set_radio_stop(False)
    assert t.run(5.0, until=lambda: t.states[-1]['safetyState']['eStop'] == 'NONE')
    assert not t.invalid
