"""The way the truck's tasks drive, and the bridge's passes on a house-numbered floor.

A task drives to the NEXT location marker of its identity (docs/tasks.md). On fleet_1983 the
houses A1..A8 alternate identities 0 and 2, so one stop task reaches at most the house after
next; the bridge takes the truck further by `pass N` tasks (agv_nodes.vda5050.task_way), one
for each marker of the stop's identity on the way before its own, and follows the truck's
reports (identities only) to the nodes it passed.
"""

from __future__ import annotations

from itertools import product

import pytest

from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.harness import submit, truck
from agv_nodes.records import codec
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.common import Action, ActionParameter, BlockingType
from agv_nodes.vda5050.order import Edge, InstantActions, Node, Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.vda5050.order_tasks import position_text
from agv_nodes.vda5050.state import ActionStatus
from agv_nodes.vda5050.task_way import one_task_way, task_legs, task_way
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope='module')
def fleet() -> TrackGraph:
    return track_graph(load_layout(layout_path('fleet_1983')))


@pytest.fixture(scope='module')
def demo() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


def passes(graph: TrackGraph, anchor: str, passed: bool, stop: str) -> list[str] | None:
    legs = task_legs(graph, anchor, passed, stop)
    return None if legs is None else [legs[0][i] for i in legs[1]]


def test_one_task_reaches_the_next_house_of_its_identity_and_no_further(fleet):
    assert one_task_way(fleet, 'A1.1', True, 'A3.1') == ['A1.1', 'A2', 'A2.1', 'A3', 'A3.1']
    # A5 is identity 0 as A3 is: the task would stop at A3.1
    assert one_task_way(fleet, 'A1.1', True, 'A5.1') is None
    # not yet passed, the start itself is the next marker of its identity
    assert one_task_way(fleet, 'A1', False, 'A1.1') == ['A1', 'A1.1']
    assert one_task_way(fleet, 'A1', False, 'A3.1') is None
    assert one_task_way(fleet, 'A1', True, 'A3.1') == ['A1', 'A1.1', 'A2', 'A2.1', 'A3', 'A3.1']


def test_the_truck_passes_each_house_of_the_stop_s_identity_before_its_own(fleet):
    assert passes(fleet, 'A1.1', True, 'A3.1') == []
    assert passes(fleet, 'A1.1', True, 'A5.1') == ['A3']
    assert passes(fleet, 'A1.1', True, 'B4.1') == ['A2', 'A4', 'A6', 'A8', 'B2']
    way, _ = task_legs(fleet, 'A1.1', True, 'B4.1')
    assert way[0] == 'A1.1' and way[-2:] == ['B4', 'B4.1'] and 'L1' in way
    # the route map's locations are on the floor once: nothing to pass to the passing places
    assert passes(fleet, 'A1.1', True, 'W1.1') == []
    assert passes(fleet, 'A1.1', True, 'W3.1') == []
    # back to where it stands: a lap, past every other 0
    assert passes(fleet, 'A1.1', True, 'A1.1') == ['A3', 'A5', 'A7', 'B1', 'B3', 'B5', 'B7']
    # not yet passed, a start of the stop's identity is passed too
    assert passes(fleet, 'A1', False, 'A3.1') == ['A1']
    assert task_way(fleet, 'A1.1', True, 'A5.1') == ['A1.1', 'A2', 'A2.1', 'A3', 'A3.1', 'A4',
                                                     'A4.1', 'A5', 'A5.1']


def test_after_its_passes_the_stop_task_meets_its_own_marker_first(fleet):
    stops = [n for n in fleet.nodes.values() if n.stoppable]
    for a, b in product(stops, stops):
        way, at = task_legs(fleet, a.id, True, b.id)
        start = at[-1] if at else 0
        assert one_task_way(fleet, way[start], True, b.id) == way[start:], (a.id, b.id)
        identity = fleet.nodes[b.id].location
        between = [n for n in way[1:start] if fleet.nodes[n].kind == 'location'
                   and fleet.nodes[n].location == identity]
        assert between == [way[k] for k in at[:-1]], (a.id, b.id)


def test_the_demonstration_room_needs_no_pass(demo):
    stops = [n.id for n in demo.nodes.values() if n.stoppable]
    for a, b in product(stops, stops):
        assert passes(demo, a, True, b) == [], (a, b)
        assert task_way(demo, a, True, b) == one_task_way(demo, a, True, b)


def test_the_pass_task_is_a_record_of_its_own_and_continues():
    record = parse_task('Pass 2').record()
    assert (record['op'], record['location'], record['then']) == ('pass', 2, 'continue')
    schema = codec()['comms_status']
    raw = schema.encode({**record, 'task_id': 4})
    assert len(raw) == 16 and raw[1] & 0x0F == 11  # byte 2 (bytes count from 1)
    assert schema.decode(raw)['op'] == 'pass'
    for text, words in (('pass', 'expected location'), ('pass 7', 'no such location marker'),
                        ('pass 2 first', "unexpected 'first'")):
        with pytest.raises(TaskError, match=words):
            parse_task(text)


def order(ids: list[str], actions: dict[str, Action]) -> Order:
    return Order(header_id=1, timestamp=common.now(), version=VERSION, manufacturer='m',
                 serial_number='s', order_id='o1', order_update_id=0,
                 nodes=[Node(node_id=n, sequence_id=2 * i, released=True,
                             actions=[actions[n]] if n in actions else [])
                        for i, n in enumerate(ids)],
                 edges=[Edge(edge_id=f'{a}-{b}', sequence_id=2 * i + 1, released=True,
                             start_node_id=a, end_node_id=b, actions=[])
                        for i, (a, b) in enumerate(zip(ids, ids[1:], strict=False))])


def placed(graph: TrackGraph, node: str) -> OrderFlow:
    """Return a flow whose truck was set down at `node` (initPosition, as the dispatcher does)."""
    flow = OrderFlow(graph)
    flow.on_instant_actions(InstantActions(
        header_id=1, timestamp=common.now(), version=VERSION, manufacturer='m',
        serial_number='s', actions=[Action(
            action_id='init', action_type='initPosition', blocking_type=BlockingType.HARD,
            action_parameters=[ActionParameter(key='lastNodeId', value=node)])]))
    assert flow.last_node_id == node
    flow.task_queued(100, position_text(graph.nodes[node]))  # the truck takes the `at` task
    flow.task_state(100, 'completed', 0, '', graph.nodes[node].location)
    return flow


def test_the_bridge_takes_the_truck_past_a_house_of_the_same_identity_by_a_pass(fleet):
    flow = placed(fleet, 'A1.1')
    ids = task_way(fleet, 'A1.1', True, 'A5.1')
    pick = Action(action_id='p', action_type='pick', blocking_type=BlockingType.HARD)
    out = flow.on_order(order(ids, {'A5.1': pick}))
    assert out.verdict == 'accepted', out.errors
    assert out.tasks == ['pass 0', 'load at 0 first']  # on past A3, then to A5.1
    for text in out.tasks:
        parse_task(text)
    # the first task: past A2 (identity 2) and on past A3 (0)
    flow.task_queued(1, out.tasks[0])
    flow.task_queued(2, out.tasks[1])
    flow.task_state(1, 'running', 0, '', 0)
    flow.task_state(1, 'running', 0, '', 2)
    assert flow.last_node_id == 'A2'
    flow.task_state(1, 'running', 0, '', 0)
    assert flow.last_node_id == 'A3'
    flow.task_state(1, 'step done', 0, '', 0)
    flow.task_state(1, 'completed', 0, '', 0)
    assert flow.last_node_id == 'A3'
    assert [a.action_status for a in flow.state_fields()['action_states']
            if a.action_id == 'p'] == [ActionStatus.WAITING]  # the pass carries no action
    # the second: the identities it reports are A4 and A5, not A2 and A3 again
    flow.task_state(2, 'running', 0, '', 0)
    assert flow.last_node_id == 'A3'
    flow.task_state(2, 'running', 0, '', 2)
    assert flow.last_node_id == 'A4'
    flow.task_state(2, 'running', 0, '', 0)
    assert flow.last_node_id == 'A5'
    flow.task_state(2, 'step done', 0, '', 0)
    assert flow.last_node_id == 'A5.1'
    flow.task_state(2, 'running', 1, '', 0)
    flow.task_state(2, 'completed', 0, '', 0)
    state = flow.state_fields()
    assert state['node_states'] == [] and state['edge_states'] == []
    assert [(a.action_id, a.action_status) for a in state['action_states']] == [
        ('p', ActionStatus.FINISHED)]


def test_an_order_one_task_cannot_drive_is_still_refused_where_no_via_helps(fleet):
    flow = placed(fleet, 'A1.1')
    # A1.1 -> A2 -> A2.1 skipping nothing, but ending at a location marker: refused as before
    out = flow.on_order(order(['A1.1', 'A2'], {}))
    assert out.verdict == 'rejected'
    # a way that is not the route map's (A2.1 straight to A4): no edge, an orderError
    out = flow.on_order(order(['A1.1', 'A2', 'A2.1', 'A4', 'A4.1'], {}))
    assert out.verdict == 'rejected'


def test_a_truck_passes_a_house_of_the_stop_s_identity_without_stopping(fleet):
    """The whole truck in lock step: at A1.1, `pass 0` then `stop at 0 first` ends at A5.1."""
    lay = load_layout(layout_path('fleet_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    h = truck('fleet_1983', start=at['A1.1'])
    submit(h, 'at 0 first')
    h.run(0.5)
    submit(h, 'pass 0')
    submit(h, 'stop at 0 first')
    a3, a5 = fleet.nodes['A3'].x, fleet.nodes['A5.1'].x
    slowest = []  # speed while between A3's stop marker and A5's location marker

    def done() -> bool:
        x, _, _, speed = h.world.pose()
        if fleet.nodes['A3.1'].x + 0.5 < x < fleet.nodes['A5'].x - 1.0:
            slowest.append(speed)
        return any("'stop at 0 first': completed" in line or 'FAILED' in line
                   for line in h.cores['communications'].notes.texts())

    assert h.run(120.0, until=done)
    reports = h.cores['communications'].notes.texts()
    assert "task 2 'pass 0': completed [last marker L0]" in reports
    assert "task 3 'stop at 0 first': completed [last marker L0]" in reports
    x = h.world.pose()[0]
    # the sensor point stops on A5.1 (the pose is the rear axle's, a wheelbase behind it)
    wheelbase = h.world.p.electruk.wheelbase
    assert a5 - 0.1 < x + wheelbase < a5 + 0.1, (x, a5)
    assert x > a3
    assert slowest and min(slowest) > 0.5  # cruising (0.7 m/s) past A3 and A4: no stop
