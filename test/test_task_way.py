"""The way the truck's tasks drive, and the bridge's via stops on a house-numbered floor.

A task drives to the NEXT location marker of its identity (docs/tasks.md). On fleet_1983 the
houses A1..A8 alternate identities 0 and 2, so one task reaches at most the house after next;
the bridge takes the truck further by via stops (agv_nodes.vda5050.task_way), each the furthest
stop marker one task reaches, and follows the truck's reports (identities only) to the nodes
it passed.
"""

from __future__ import annotations

from itertools import product

import pytest

from agv_nodes.communications.task_language import parse_task
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
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


def vias(graph: TrackGraph, anchor: str, passed: bool, stop: str) -> list[str] | None:
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


def test_via_stops_are_the_furthest_stop_each_task_reaches(fleet):
    assert vias(fleet, 'A1.1', True, 'A3.1') == []
    assert vias(fleet, 'A1.1', True, 'A5.1') == ['A3.1']
    assert vias(fleet, 'A1.1', True, 'B4.1') == ['A3.1', 'A5.1', 'A7.1', 'B1.1', 'B3.1']
    way, _ = task_legs(fleet, 'A1.1', True, 'B4.1')
    assert way[0] == 'A1.1' and way[-2:] == ['B4', 'B4.1'] and 'L1' in way
    # the route map's locations are on the floor once: no via to the passing places
    assert vias(fleet, 'A1.1', True, 'W1.1') == []
    assert vias(fleet, 'A1.1', True, 'W3.1') == []
    # back to where it stands: a lap, house by house
    assert vias(fleet, 'A1.1', True, 'A1.1') == ['A3.1', 'A5.1', 'A7.1', 'B1.1', 'B3.1',
                                                 'B5.1', 'B7.1']
    assert task_way(fleet, 'A1.1', True, 'A5.1') == ['A1.1', 'A2', 'A2.1', 'A3', 'A3.1', 'A4',
                                                     'A4.1', 'A5', 'A5.1']


def test_every_leg_is_one_task_and_the_legs_make_the_way(fleet):
    stops = [n for n in fleet.nodes.values() if n.stoppable]
    for a, b in product(stops, stops):
        way, at = task_legs(fleet, a.id, True, b.id)
        ends = [0, *at, len(way) - 1]
        for i, j in zip(ends, ends[1:], strict=False):
            assert one_task_way(fleet, way[i], True, way[j]) == way[i:j + 1], (a.id, b.id)


def test_the_demonstration_room_needs_no_via_stop(demo):
    stops = [n.id for n in demo.nodes.values() if n.stoppable]
    for a, b in product(stops, stops):
        assert vias(demo, a, True, b) == [], (a, b)
        assert task_way(demo, a, True, b) == one_task_way(demo, a, True, b)


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


def test_the_bridge_takes_the_truck_past_a_house_of_the_same_identity_by_a_via_stop(fleet):
    flow = placed(fleet, 'A1.1')
    ids = task_way(fleet, 'A1.1', True, 'A5.1')
    pick = Action(action_id='p', action_type='pick', blocking_type=BlockingType.HARD)
    out = flow.on_order(order(ids, {'A5.1': pick}))
    assert out.verdict == 'accepted', out.errors
    assert out.tasks == ['stop at 0 first', 'load at 0 first']  # A3.1, then A5.1
    for text in out.tasks:
        parse_task(text)
    # the first task: past A2 (identity 2) to A3 (0) and its stop marker
    flow.task_queued(1, out.tasks[0])
    flow.task_queued(2, out.tasks[1])
    flow.task_state(1, 'running', 0, '', 0)
    flow.task_state(1, 'running', 0, '', 2)
    assert flow.last_node_id == 'A2'
    flow.task_state(1, 'running', 0, '', 0)
    assert flow.last_node_id == 'A3'
    flow.task_state(1, 'completed', 0, '', 0)
    assert flow.last_node_id == 'A3.1'
    assert [a.action_status for a in flow.state_fields()['action_states']
            if a.action_id == 'p'] == [ActionStatus.WAITING]  # the via stop carries no action
    # the second: the identities it reports are A4 and A5, not A2 and A3 again
    flow.task_state(2, 'running', 0, '', 0)
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
