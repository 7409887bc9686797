"""The bridge's core without ROS or MQTT: JSON in, tasks and messages out (agv_nodes.vda5050).

The truck's side is played with the lines its communications node writes
(agv_nodes.communications.report_line), in the order the truck writes them.
"""

from __future__ import annotations

import json

import pytest
from vda5050_master import action, path, stamp

from agv_nodes.communications.report_line import progress_line, queued_line
from agv_nodes.communications.task_language import parse_task
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.vda5050.bridge import BridgeCore
from agv_nodes.vda5050.codec import parse, to_json
from agv_nodes.vda5050.connection import ConnectionState
from agv_nodes.vda5050.state import State
from agv_nodes.vda5050.truck_factsheet import MIN_STATE_INTERVAL, truck_factsheet
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(60)
QUIET = {'cause': 'none', 'subsystem': 'none', 'detail': 'none', 'location': 0xFF, 'step': 0}


@pytest.fixture(scope='module')
def graph() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


@pytest.fixture
def core(graph: TrackGraph) -> BridgeCore:
    return BridgeCore(graph, 'agv_nodes', 'agv1',
                      factsheet=lambda n: truck_factsheet('agv_nodes', 'agv1', n))


def order_json(order_id: str, update: int, nodes: list[dict], edges: list[dict]) -> str:
    return json.dumps({'headerId': 0, 'timestamp': stamp(), 'version': '2.1.0',
                       'manufacturer': 'agv_nodes', 'serialNumber': 'agv1', 'orderId': order_id,
                       'orderUpdateId': update, 'nodes': nodes, 'edges': edges})


def states(out) -> list[State]:
    return [m for name, m in out.messages if name == 'state']


def test_an_order_runs_to_its_end_on_the_truck_s_report_lines(core):
    nodes, edges = path(['L0', 'W0.1', 'L2', 'W2.1'],
                        actions={'W0.1': [action('pick', 'p')], 'W2.1': [action('drop', 'd')]})
    out = core.on_message('order', order_json('o1', 0, nodes, edges), 0.0)
    assert out.tasks == ['load at 0 first', 'unload at 2 first']
    assert all(parse_task(t) for t in out.tasks)
    assert states(out)[0].order_id == 'o1'
    t = 1.0
    lines = [queued_line(1, out.tasks[0], 1), queued_line(2, out.tasks[1], 2)]
    for task_id, text, stops_at in ((1, out.tasks[0], 0), (2, out.tasks[1], 2)):
        lines += [progress_line(task_id, text, {**QUIET, 'state': 'running', 'location': loc})
                  for loc in ((0xFF, 0) if stops_at == 0 else (0, 2))]
        lines += [progress_line(task_id, text, {**QUIET, 'state': 'step_done',
                                                'location': stops_at}),
                  progress_line(task_id, text, {**QUIET, 'state': 'completed',
                                                'location': stops_at})]
    last = None
    for line in lines:
        t += 1.0  # apart by more than minStateInterval: every change is sent at once
        for s in states(core.on_report(line, t)):
            last = s
    assert last is not None
    assert (last.last_node_id, last.node_states, last.edge_states) == ('W2.1', [], [])
    assert {a.action_id: a.action_status for a in last.action_states} == {
        'p': 'FINISHED', 'd': 'FINISHED'}
    # header ids count per topic from 0 (6.4); every state is valid by the models
    ids = [core.state().header_id]
    assert ids[0] > 1 and parse(State, to_json(core.state())).header_id == ids[0] + 1


def test_a_message_that_is_not_vda5050_is_a_validation_error_naming_the_fields(core):
    out = core.on_message('order', '{"headerId": 7, "orderId": 5}', 0.0)
    (error,) = states(out)[0].errors
    refs = {r.reference_key: r.reference_value for r in error.error_references}
    assert error.error_type == 'validationError' and error.error_level == 'WARNING'
    assert refs['topic'] == 'order' and refs['headerId'] == '7'
    assert {'orderId', 'nodes', 'edges', 'orderUpdateId'} <= set(refs)
    assert core.counts['invalid'] == 1 and 'orderId' in core.last_invalid
    out = core.on_message('instantActions', b'not json', 1.0)
    (error,) = states(out)[0].errors
    assert {r.reference_key for r in error.error_references} >= {'topic', '$'}
    # a valid message clears the warning; an accepted order clears the error (6.6.4.1)
    nodes, edges = path(['L0', 'W0.1'])
    out = core.on_message('order', order_json('o1', 0, nodes, edges), 2.0)
    assert core.last_invalid == '' and states(out)[0].errors == []


def test_a_burst_of_changes_goes_out_as_one_state_after_min_state_interval(core):
    nodes, edges = path(['L0', 'W0.1'])
    out = core.on_message('order', order_json('o1', 0, nodes, edges), 0.0)
    assert len(states(out)) == 1
    text = out.tasks[0]
    held = core.on_report(queued_line(1, text, 1), 0.01)
    for state in ('running', 'step_done'):
        held.extend(core.on_report(progress_line(1, text, {**QUIET, 'state': state,
                                                           'location': 0}), 0.02))
    assert states(held) == []  # within minStateInterval of the last one
    assert states(core.tick(MIN_STATE_INTERVAL / 2)) == []
    (sent,) = states(core.tick(MIN_STATE_INTERVAL))
    assert sent.last_node_id == 'W0.1' and sent.node_states == []  # the held changes
    assert states(core.tick(2 * MIN_STATE_INTERVAL)) == []  # nothing new: nothing sent


def test_state_goes_out_at_least_every_state_interval(graph):
    core = BridgeCore(graph, 'm', 's', state_interval=5.0)
    assert len(states(core.tick(0.0))) == 1
    assert states(core.tick(4.9)) == []
    assert len(states(core.tick(5.0))) == 1


def test_connection_and_factsheet_requests(core):
    online = core.connection(ConnectionState.ONLINE)
    assert (online.connection_state, online.header_id, online.serial_number) == (
        'ONLINE', 0, 'agv1')
    assert core.connection(ConnectionState.OFFLINE).header_id == 1
    body = json.dumps({'headerId': 0, 'timestamp': stamp(), 'version': '2.1.0',
                       'manufacturer': 'agv_nodes', 'serialNumber': 'agv1', 'actions': [
                           {'actionType': 'factsheetRequest', 'actionId': 'f1',
                            'blockingType': 'NONE'}]})
    out = core.on_message('instantActions', body, 0.0)
    names = [name for name, _m in out.messages]
    assert names == ['factsheet', 'state']
    assert {a.action_id: a.action_status for a in states(out)[0].action_states} == {
        'f1': 'FINISHED'}
