"""VDA 5050 2.1 order handling (agv_nodes.vda5050.order_flow) on demo_1983's track graph.

Orders go in, task texts come out (each must parse in the task language), and the truck's
report lines drive nodeStates, edgeStates and actionStates; every state the flow reports must
make a valid State message. demo_1983 is the one-way loop
L0 -> W0.1 -> L2 -> W2.1 -> W2.2 -> L1 -> (SRM) -> L3 -> (SRM) -> L0 with branches
L1 -> W1.1 -> L3 and L3 -> W3.1 -> L0.
"""

from __future__ import annotations

import pytest

from agv_nodes.communications.task_language import parse_task
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.codec import parse, to_json
from agv_nodes.vda5050.common import Action, ActionParameter, BlockingType
from agv_nodes.vda5050.order import Edge, InstantActions, Node, Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.vda5050.order_tasks import Outcome
from agv_nodes.vda5050.state import (
    ActionStatus,
    BatteryState,
    EStop,
    OperatingMode,
    SafetyState,
    State,
)
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(120)

LOOP = ['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'W1.1', 'L3', 'W3.1']


@pytest.fixture(scope='module')
def graph() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


@pytest.fixture
def flow(graph: TrackGraph) -> OrderFlow:
    return OrderFlow(graph)


def action(action_id: str, kind: str, **parameters: object) -> Action:
    return Action(action_id=action_id, action_type=kind, blocking_type=BlockingType.HARD,
                  action_parameters=[ActionParameter(key=k, value=v)
                                     for k, v in parameters.items()] or None)


def make_order(ids: list[str], order_id: str = 'o1', update: int = 0, first: int = 0,
               released: int | None = None, actions: dict[str, list[Action]] | None = None,
               header_id: int = 1) -> Order:
    """Return an order along `ids`; its first `released` nodes (default all) are the base."""
    released = len(ids) if released is None else released
    actions = actions or {}
    nodes = [Node(node_id=n, sequence_id=first + 2 * i, released=i < released,
                  actions=actions.get(n, [])) for i, n in enumerate(ids)]
    edges = [Edge(edge_id=f'{a}-{b}', sequence_id=first + 2 * i + 1, released=i + 1 < released,
                  start_node_id=a, end_node_id=b, actions=[])
             for i, (a, b) in enumerate(zip(ids, ids[1:], strict=False))]
    return Order(header_id=header_id, timestamp=common.now(), version=VERSION, manufacturer='m',
                 serial_number='s', order_id=order_id, order_update_id=update, nodes=nodes,
                 edges=edges)


def instant(*actions: Action) -> InstantActions:
    return InstantActions(header_id=7, timestamp=common.now(), version=VERSION,
                          manufacturer='m', serial_number='s', actions=list(actions))


def full_state(flow: OrderFlow) -> State:
    """Return a whole State with the flow's fields, checked to survive the wire both ways."""
    state = State(header_id=0, timestamp=common.now(), version=VERSION, manufacturer='x',
                  serial_number='y', battery_state=BatteryState(battery_charge=80,
                                                                charging=False),
                  operating_mode=OperatingMode.AUTOMATIC,
                  safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
                  **flow.state_fields())
    assert parse(State, to_json(state)) == state
    return state


def tasks_of(outcome: Outcome) -> list[str]:
    for text in outcome.tasks:
        parse_task(text)  # raises TaskError if the truck could not take it
    return outcome.tasks


def nodes(flow: OrderFlow) -> list[str]:
    return [n.node_id for n in full_state(flow).node_states]


def edges(flow: OrderFlow) -> list[str]:
    return [e.edge_id for e in full_state(flow).edge_states]


def actions(flow: OrderFlow) -> dict[str, ActionStatus]:
    return {a.action_id: a.action_status for a in full_state(flow).action_states}


def errors(flow: OrderFlow) -> list[tuple[str, str]]:
    return [(e.error_type, e.error_level) for e in full_state(flow).errors]


def refs(outcome: Outcome) -> list[dict[str, str]]:
    return [{r.reference_key: r.reference_value for r in e.error_references or ()}
            for e in outcome.errors]


def drive(flow: OrderFlow, task_id: int, text: str, markers: list[int], start: int | None,
          steps: int = 2) -> None:
    """Report one task: queued, its goto past `markers`, then its other step."""
    flow.task_queued(task_id, text)
    flow.task_state(task_id, 'running', 0, '', start)
    assert flow.driving
    for marker in markers:
        flow.task_state(task_id, 'running', 0, '', marker)
    last = markers[-1] if markers else start
    flow.task_state(task_id, 'step done', 0, '', last)
    assert not flow.driving
    if steps == 2:
        flow.task_state(task_id, 'running', 1, '', last)
    flow.task_state(task_id, 'completed', 0, '', last)


def loop_order(**kw: object) -> Order:
    return make_order(LOOP, actions={'W1.1': [action('a1', 'pick')],
                                     'W3.1': [action('a2', 'drop')]}, **kw)


def test_an_order_round_the_loop_picks_and_drops_and_ends_empty(flow):
    out = flow.on_order(loop_order())
    assert out.verdict == 'accepted' and out.publish_state
    assert tasks_of(out) == ['load at 1 first', 'unload at 3 first']
    # 6.10.6: the truck has read no card yet: L0, the first ahead, is a node to traverse
    assert flow.last_node_id == '' and nodes(flow) == LOOP
    assert edges(flow)[0] == 'L0-W0.1' and len(edges(flow)) == 8
    assert actions(flow) == {'a1': ActionStatus.WAITING, 'a2': ActionStatus.WAITING}
    flow.task_queued(6, 'load at 1 first')
    flow.task_state(6, 'running', 0, '', None)
    assert flow.driving and nodes(flow) == LOOP
    assert flow.task_state(6, 'running', 0, '', 0).publish_state  # the start node read
    assert (flow.last_node_id, flow.last_node_sequence_id) == ('L0', 0)
    assert nodes(flow) == LOOP[1:]
    assert flow.task_state(6, 'running', 0, '', 2).publish_state
    assert nodes(flow) == LOOP[3:] and flow.last_node_id == 'L2'
    assert (flow.last_node_sequence_id, edges(flow)[0]) == (4, 'L2-W2.1')
    assert not flow.task_state(6, 'running', 0, '', 2).publish_state  # a repeat: no passage
    flow.task_state(6, 'running', 0, '', 1)
    assert nodes(flow) == LOOP[6:]
    flow.task_state(6, 'step done', 0, '', 1)
    assert (flow.last_node_id, flow.last_node_sequence_id) == ('W1.1', 12)
    assert not flow.driving and actions(flow)['a1'] == ActionStatus.RUNNING
    flow.task_state(6, 'running', 1, '', 1)
    assert not flow.driving
    flow.task_state(6, 'completed', 0, '', 1)
    assert actions(flow)['a1'] == ActionStatus.FINISHED
    drive(flow, 7, 'unload at 3 first', [3], 1)
    assert nodes(flow) == [] and edges(flow) == []
    assert actions(flow) == {'a1': ActionStatus.FINISHED, 'a2': ActionStatus.FINISHED}
    assert (flow.last_node_id, flow.last_node_sequence_id) == ('W3.1', 16)
    assert not flow.driving and errors(flow) == []


def test_task_texts_for_wait_stop_and_the_second_marker(flow):
    out = flow.on_order(make_order(LOOP[:5], actions={'W0.1': [action('w', 'wait',
                                                                      duration=5.0)]}))
    assert tasks_of(out) == ['wait at 0 for 5 s first', 'stop at 2 second']
    assert parse_task('stop at 2 second').marker == 'second'


def test_only_the_base_becomes_tasks_and_an_update_stitches_at_its_end(flow):
    out = flow.on_order(loop_order(released=4))  # base L0..W2.1, horizon W2.2..W3.1
    assert tasks_of(out) == ['stop at 2 first']
    state = full_state(flow)
    assert [n.released for n in state.node_states] == [True] * 4 + [False] * 5
    assert [e.released for e in state.edge_states] == [True] * 3 + [False] * 5
    assert actions(flow) == {'a1': ActionStatus.WAITING, 'a2': ActionStatus.WAITING}
    assert state.new_base_request
    update = make_order(LOOP[3:], update=1, first=6,
                        actions={'W1.1': [action('a1', 'pick')], 'W3.1': [action('a2', 'drop')]})
    out = flow.on_order(update)
    assert out.verdict == 'updated'
    assert tasks_of(out) == ['load at 1 first', 'unload at 3 first']
    assert flow.order_update_id == 1 and nodes(flow) == LOOP
    assert all(n.released for n in full_state(flow).node_states)
    assert len(edges(flow)) == 8 and not full_state(flow).new_base_request
    drive(flow, 1, 'stop at 2 first', [2], None, steps=1)
    assert flow.last_node_id == 'W2.1' and nodes(flow) == LOOP[4:]
    drive(flow, 2, 'load at 1 first', [1], 2)
    drive(flow, 3, 'unload at 3 first', [3], 1)
    assert nodes(flow) == [] and set(actions(flow).values()) == {ActionStatus.FINISHED}


def test_an_update_after_the_order_ended_continues_from_the_last_node(flow):
    tasks_of(flow.on_order(make_order(LOOP[:4])))
    drive(flow, 1, 'stop at 2 first', [2], None, steps=1)
    out = flow.on_order(make_order(['W2.1', 'W2.2', 'L1', 'W1.1'], update=1, first=6))
    assert out.verdict == 'updated' and tasks_of(out) == ['stop at 1 first']
    bad = flow.on_order(make_order(['W2.2', 'L1', 'W1.1'], update=2, first=8))
    assert bad.verdict == 'rejected' and errors(flow) == [('orderUpdateError', 'WARNING')]
    assert refs(bad)[0]['nodeId'] == 'W2.2'


def test_a_lower_update_is_an_error_and_the_same_update_is_ignored(flow):
    flow.on_order(loop_order(released=4))
    flow.on_order(make_order(LOOP[3:6], update=2, first=6, released=1))
    before = flow.state_fields()
    same = flow.on_order(make_order(LOOP[3:], update=2, first=6))
    assert same.verdict == 'ignored' and same.tasks == [] and same.errors == []
    assert flow.state_fields() == before
    lower = flow.on_order(make_order(LOOP[3:], update=1, first=6))
    assert lower.verdict == 'rejected' and lower.tasks == []
    assert [e.error_type for e in lower.errors] == ['orderUpdateError']
    assert refs(lower)[0]['orderUpdateId'] == '1' and refs(lower)[0]['orderId'] == 'o1'
    assert flow.state_fields()['node_states'] == before['node_states']
    assert flow.order_update_id == 2


def test_an_update_must_start_at_the_decision_point(flow):
    flow.on_order(loop_order(released=4))
    out = flow.on_order(make_order(LOOP[4:], update=1, first=8))
    assert out.verdict == 'rejected' and refs(out)[0]['nodeId'] == 'W2.2'
    out = flow.on_order(make_order(LOOP[3:], update=1, first=8))  # W2.1, other sequenceId
    assert out.verdict == 'rejected' and out.errors[0].error_type == 'orderUpdateError'


def test_a_new_order_id_while_the_order_is_active_is_rejected(flow):
    flow.on_order(loop_order())
    out = flow.on_order(make_order(LOOP[:2], order_id='o2'))
    assert out.verdict == 'rejected' and out.errors[0].error_type == 'orderUpdateError'
    assert refs(out)[0]['orderId'] == 'o2' and flow.order_id == 'o1'
    assert len(nodes(flow)) == 9  # L0 too: the truck has not read it yet


def _order_error(flow: OrderFlow, order: Order) -> list[dict[str, str]]:
    out = flow.on_order(order)
    assert out.verdict == 'rejected' and out.tasks == []
    assert {e.error_type for e in out.errors} == {'orderError'}
    assert {e.error_level for e in out.errors} == {'WARNING'}
    assert all(r['headerId'] == str(order.header_id) for r in refs(out))
    assert flow.order_id == '' and nodes(flow) == []
    return refs(out)


def test_order_errors_name_the_offending_fields(flow):
    assert _order_error(flow, make_order(['L0', 'X9']))[0]['nodeId'] == 'X9'
    order = make_order(LOOP[:2])
    order.edges[0].edge_id = 'shortcut'
    assert _order_error(flow, order)[0]['edgeId'] == 'shortcut'
    order = make_order(LOOP[:2])
    order.edges[0].end_node_id = 'L2'
    assert _order_error(flow, order)[0]['edgeId'] == 'L0-W0.1'
    order = make_order(LOOP[:3])
    order.nodes[2].sequence_id = 3
    assert _order_error(flow, order)[0].items() >= {('nodeId', 'L2'), ('sequenceId', '3')}
    order = make_order(LOOP[:3])
    order.edges[1].sequence_id = 4
    assert _order_error(flow, order)[0]['edgeId'] == 'W0.1-L2'
    assert _order_error(flow, make_order(LOOP[:3], first=1))[0]['sequenceId'] == '1'
    order = make_order(LOOP[:4], released=2)
    order.nodes[3].released = True  # released after an unreleased one
    assert _order_error(flow, order)[0]['nodeId'] == 'W2.1'
    order = make_order(LOOP[:2], released=1)
    order.edges[0].released = True  # the base would end with an edge
    assert _order_error(flow, order)[0]['edgeId'] == 'L0-W0.1'
    order = make_order(LOOP[:3])
    order.edges.pop()
    assert 'orderId' in _order_error(flow, order)[0]
    # the base ends on a location marker: nowhere to stop
    assert _order_error(flow, make_order(LOOP[:3]))[0]['nodeId'] == 'L2'


def test_order_errors_for_actions(flow):
    one = _order_error(flow, make_order(LOOP[:2], actions={'W0.1': [action('c', 'charge')]}))
    assert one[0]['actionType'] == 'charge' and one[0]['actionId'] == 'c'
    one = _order_error(flow, make_order(LOOP[:4], actions={'L2': [action('p', 'pick')]}))
    assert one[0]['nodeId'] == 'L2' and one[0]['actionId'] == 'p'
    order = make_order(LOOP[:2])
    order.edges[0].actions = [action('e', 'pick')]
    one = _order_error(flow, order)
    assert one[0]['edgeId'] == 'L0-W0.1' and one[0]['actionId'] == 'e'
    one = _order_error(flow, make_order(LOOP[:2], actions={'L0': [action('s', 'drop')]}))
    assert one[0]['nodeId'] == 'L0' and one[0]['actionId'] == 's'
    two = [action('p', 'pick'), action('w', 'wait', duration=3)]
    one = _order_error(flow, make_order(LOOP[:2], actions={'W0.1': two}))
    assert one[0]['nodeId'] == 'W0.1'
    for bad in ({'duration': 256}, {'duration': -1}, {'duration': 2.5}, {'duration': 'x'},
                {'duration': True}, {}):
        one = _order_error(flow, make_order(LOOP[:2],
                                            actions={'W0.1': [action('w', 'wait', **bad)]}))
        assert one[0]['actionId'] == 'w' and one[0]['actionParameter'] == 'duration'
    twice = {'W0.1': [action('p', 'pick')], 'W2.1': [action('p', 'drop')]}
    assert _order_error(flow, make_order(LOOP[:4], actions=twice))[0]['actionId'] == 'p'


def test_no_route_to_a_start_out_of_reach(flow):
    out = flow.on_order(make_order(LOOP[1:4]))  # the truck has passed nothing: L0 is first
    assert out.verdict == 'rejected' and out.errors[0].error_type == 'noRouteError'
    assert refs(out)[0]['nodeId'] == 'W0.1'
    flow.on_order(make_order(LOOP[:2]))
    drive(flow, 1, 'stop at 0 first', [0], None, steps=1)
    out = flow.on_order(make_order(LOOP[:2], order_id='o2'))  # the truck is on W0.1 now
    assert out.verdict == 'rejected' and refs(out)[0]['nodeId'] == 'L0'
    out = flow.on_order(make_order(LOOP[1:4], order_id='o2'))
    assert out.verdict == 'accepted' and tasks_of(out) == ['stop at 2 first']


def test_no_route_where_the_task_language_cannot_drive_the_way(flow):
    # W2.1 to W2.2 directly: a task to W2.2 passes L2 first, a lap on
    order = make_order(LOOP[:5], actions={'W2.1': [action('w', 'wait', duration=0)]})
    out = flow.on_order(order)
    assert [e.error_type for e in out.errors] == ['noRouteError']
    assert refs(out)[0]['nodeId'] == 'W2.2'
    # through the station W1.1 without stopping: the truck leaves L1 by its SRM instead
    out = flow.on_order(make_order(LOOP, actions={'W3.1': [action('d', 'drop')]}))
    assert refs(out)[0]['nodeId'] == 'W3.1' and out.errors[0].error_type == 'noRouteError'
    # a task stops at the first marker of its location it meets, not a lap later
    lap = ['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'L3', 'L0', 'W0.1']
    out = flow.on_order(make_order(lap))
    assert refs(out)[0]['nodeId'] == 'W0.1' and out.errors[0].error_type == 'noRouteError'
    # the same way by the SRM edge is the truck's
    loop = [n for n in LOOP if n != 'W1.1']
    out = flow.on_order(make_order(loop, actions={'W3.1': [action('d', 'drop')]}))
    assert tasks_of(out) == ['unload at 3 first']


def test_cancel_order_aborts_and_fails_the_rest(flow):
    flow.on_order(loop_order())
    flow.task_queued(1, 'load at 1 first')
    flow.task_queued(2, 'unload at 3 first')
    flow.task_state(1, 'running', 0, '', 2)
    out = flow.on_instant_actions(instant(action('c1', 'cancelOrder')))
    assert tasks_of(out) == ['abort'] and out.publish_state
    assert actions(flow) == {'a1': ActionStatus.FAILED, 'a2': ActionStatus.FAILED,
                             'c1': ActionStatus.RUNNING}
    assert nodes(flow) == [] and edges(flow) == [] and flow.order_id == 'o1'
    assert flow.last_node_id == 'L2'
    flow.task_queued(3, 'abort')
    assert flow.task_state(3, 'completed', 0, '', 2).publish_state
    assert actions(flow)['c1'] == ActionStatus.FINISHED and not flow.driving
    # a repeat of the same actionId is ignored; a new cancel finds no order
    assert flow.on_instant_actions(instant(action('c1', 'cancelOrder'))).tasks == []
    again = flow.on_instant_actions(instant(action('c2', 'cancelOrder')))
    assert again.tasks == [] and actions(flow)['c2'] == ActionStatus.FAILED
    assert errors(flow) == [('noOrderToCancel', 'WARNING')]


def test_cancel_order_without_an_order(flow):
    out = flow.on_instant_actions(instant(action('c', 'cancelOrder')))
    assert out.tasks == [] and actions(flow) == {'c': ActionStatus.FAILED}
    assert out.errors[0].error_type == 'noOrderToCancel' and refs(out)[0]['actionId'] == 'c'


def test_a_failed_task_fails_the_order_and_drops_the_queue(flow):
    flow.on_order(loop_order())
    flow.task_queued(1, 'load at 1 first')
    flow.task_queued(2, 'unload at 3 first')
    flow.task_state(1, 'running', 0, '', 2)
    out = flow.task_state(1, 'FAILED', 0, 'lost wire (route)', 2)
    assert tasks_of(out) == ['abort'] and out.publish_state
    assert actions(flow) == {'a1': ActionStatus.FAILED, 'a2': ActionStatus.FAILED}
    assert 'lost wire' in full_state(flow).action_states[0].result_description
    assert nodes(flow) == [] and edges(flow) == [] and not flow.driving
    error = full_state(flow).errors[0]
    assert (error.error_type, error.error_level) == ('taskFailed', 'WARNING')
    assert 'lost wire (route)' in error.error_description
    references = {(r.reference_key, r.reference_value) for r in error.error_references}
    assert references >= {('nodeId', 'W1.1'), ('actionId', 'a1'), ('taskId', '1')}
    flow.task_queued(3, 'abort')
    flow.task_state(3, 'completed', 0, '', 2)
    # on from the last node, L2, which the truck has passed: W2.1 is a lap away
    out = flow.on_order(make_order(LOOP[2:4], order_id='o2'))
    assert out.verdict == 'rejected' and refs(out)[0]['nodeId'] == 'W2.1'
    out = flow.on_order(make_order(LOOP[2:7], order_id='o2'))
    assert out.verdict == 'accepted' and tasks_of(out) == ['stop at 1 first']
    assert errors(flow) == [] and actions(flow) == {}


def test_an_abort_the_bridge_did_not_send_does_not_stop_the_pairing(flow):
    flow.on_order(make_order(LOOP[:4], actions={'W0.1': [action('p', 'pick')]}))
    flow.task_queued(1, 'load at 0 first')
    flow.task_queued(2, 'stop at 2 first')
    assert flow.task_state(1, 'FAILED', 0, 'load failed (load)', 0).tasks == ['abort']
    # without the abort the truck goes on with the failed order's task: driving, no progress
    flow.task_state(2, 'running', 0, '', 0)
    assert flow.driving and nodes(flow) == []
    flow.task_state(2, 'completed', 0, '', 2)
    assert flow.last_node_id == 'L0' and not flow.driving
    out = flow.on_order(make_order(LOOP[:4], order_id='o2'))  # the last node: L0
    assert tasks_of(out) == ['stop at 2 first']
    assert not flow.task_queued(3, 'stop at 2 first')  # the abort was left out: paired on
    flow.task_state(3, 'completed', 0, '', 2)
    assert flow.last_node_id == 'W2.1' and errors(flow) == []


def test_a_rejected_last_task_needs_no_abort(flow):
    flow.on_order(make_order(LOOP[:2]))
    flow.task_queued(4, 'stop at 0 first')
    out = flow.task_state(4, 'rejected', 0, 'bad task', None)
    assert out.tasks == [] and errors(flow) == [('taskFailed', 'WARNING')]


def test_state_and_factsheet_requests_and_a_pause_taken_back(flow):
    out = flow.on_instant_actions(instant(action('s', 'stateRequest'),
                                          action('f', 'factsheetRequest'),
                                          action('p', 'startPause'), action('q', 'stopPause'),
                                          action('x', 'honk')))
    assert out.publish_state and out.publish_factsheet and out.tasks == ['pause', 'resume']
    # the stopPause overtakes the startPause before the truck has said it is at rest; the truck
    # is not paused, so the stopPause has nothing to wait for (test/test_pause_bridge.py: more)
    assert actions(flow) == {'s': ActionStatus.FINISHED, 'f': ActionStatus.FINISHED,
                             'p': ActionStatus.FAILED, 'q': ActionStatus.FINISHED,
                             'x': ActionStatus.FAILED}
    states = {a.action_id: a for a in full_state(flow).action_states}
    assert states['p'].result_description == 'overtaken by stopPause q'
    assert [(e.error_type, r['actionId']) for e, r in zip(out.errors, refs(out),
                                                          strict=True)] == [
        ('instantActionError', 'x')]
    # a new order drops the ended instant actions' states (6.10.6)
    flow.on_order(make_order(LOOP[:2]))
    assert actions(flow) == {}


def test_errors_stay_until_an_order_is_accepted(flow):
    flow.on_order(make_order(['L0', 'X9']))  # an unknown node, and so an unknown edge
    flow.on_order(make_order(LOOP[1:2]))
    assert errors(flow) == [('orderError', 'WARNING')] * 2 + [('noRouteError', 'WARNING')]
    flow.on_order(make_order(['L0', 'X9']))  # the same errors once
    flow.on_instant_actions(instant(action('s', 'stateRequest')))
    assert len(errors(flow)) == 3
    assert flow.on_order(make_order(LOOP[:2])).verdict == 'accepted'
    assert errors(flow) == []


def test_a_task_the_bridge_did_not_send_is_a_fatal_bridge_error(flow):
    flow.on_order(make_order(LOOP[:2]))
    assert flow.task_queued(3, 'stop at 2 first')
    assert errors(flow) == [('bridgeError', 'FATAL')]
    assert not flow.task_queued(4, 'stop at 0 first')  # ours still pairs
    flow.task_state(4, 'completed', 0, '', 0)
    assert nodes(flow) == [] and flow.last_node_id == 'W0.1'


def test_a_state_without_an_order_is_valid(flow):
    state = full_state(flow)
    assert (state.order_id, state.last_node_id, state.driving) == ('', '', False)
    assert state.node_states == [] and state.action_states == [] and state.paused is False


def test_init_position_places_a_truck_at_a_stop_marker(flow):
    out = flow.on_instant_actions(instant(action('i1', 'initPosition', lastNodeId='W2.1')))
    assert actions(flow) == {'i1': ActionStatus.FINISHED} and out.errors == []
    assert (flow.last_node_id, flow.last_node_sequence_id) == ('W2.1', 0)
    # an order now starts there, and its way from W2.1 is the truck's
    taken = flow.on_order(make_order(['W2.1', 'W2.2', 'L1', 'W1.1']))
    assert taken.verdict == 'accepted' and taken.tasks == ['stop at 1 first']
    # not while an order runs, and only at a stop marker
    out = flow.on_instant_actions(instant(action('i2', 'initPosition', lastNodeId='W0.1'),
                                          action('i3', 'initPosition', lastNodeId='L2')))
    assert actions(flow)['i2'] == actions(flow)['i3'] == ActionStatus.FAILED
    assert [e.error_type for e in out.errors] == ['instantActionError'] * 2
    assert flow.last_node_id == 'W2.1'
    fresh = OrderFlow(flow.graph)
    fresh.on_instant_actions(instant(action('i4', 'initPosition', lastNodeId='L2')))
    assert fresh.last_node_id == '' and actions(fresh) == {'i4': ActionStatus.FAILED}
