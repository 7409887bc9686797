"""The `at` task: a truck set down at a stop marker is told where it stands (a modern addition).

The 1983 truck knows where it is only from the markers it passes. Set down by hand at W1.1 of
demo_1983 it does not know that leaving W1 starts L1's SRM, and runs off the end of W1's wire;
told `at 1 first`, it leaves as from a stop of its own. The task text, the comms_status record,
the executive's taking and refusing it, the bridge's initPosition that sends it, and the
whole truck in lock step.
"""

from __future__ import annotations

from typing import Any

import pytest

from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.communications.report_line import Progress, progress_line, queued_line, read_report
from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.harness import submit, truck
from agv_nodes.records import codec
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.bridge import BridgeCore
from agv_nodes.vda5050.codec import to_json
from agv_nodes.vda5050.common import Action, ActionParameter, BlockingType
from agv_nodes.vda5050.order import Edge, InstantActions, Node, Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.vda5050.state import ActionStatus
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(300)

SRM_MAP = ['1:15', '3:15']  # demo_1983's route map


# -- the task text and its record -----------------------------------------------------------
@pytest.mark.parametrize('text, location, marker', [
    ('at 1', 1, 'first'),
    ('at 1 first', 1, 'first'),
    ('AT 2 Second', 2, 'second'),
    ('at 3 first', 3, 'first'),
])
def test_the_at_task_names_a_location_and_its_stop_marker(text, location, marker):
    record = parse_task(text).record()
    assert (record['op'], record['location'], record['marker']) == ('at', location, marker)
    assert record['then'] == 'stay' and record['destination'] == 0xFF
    schema = codec()['comms_status']
    raw = schema.encode({**record, 'task_id': 9})
    assert len(raw) == 16  # the fixed record, with op 10 in byte 2
    decoded = schema.decode(raw)
    assert (decoded['op'], decoded['location'], decoded['marker']) == ('at', location, marker)


@pytest.mark.parametrize('text, column, words', [
    ('at', 3, 'expected location'),
    ('at 7', 4, 'no such location marker'),
    ('at 2 third', 6, "unexpected 'third'"),
    ('at 2 first then second', 12, "unexpected 'then'"),  # it stands at one stop marker
    ('at 2 second then continue', 13, "unexpected 'then'"),  # it moves nowhere
])
def test_a_bad_at_task_names_the_column_and_reason(text, column, words):
    with pytest.raises(TaskError) as info:
        parse_task(text)
    assert info.value.column == column and words in str(info.value)


def test_communications_queues_the_at_task_as_any_other():
    comms = CommunicationsCore()
    out = comms.on_task('at 1 first', 0.0)
    assert out['comms_status']['op'] == 'at' and out['comms_status']['location'] == 1
    assert comms.notes.texts()[-1] == "task 1 queued: 'at 1 first' (1 in queue)"


# -- the executive --------------------------------------------------------------------------
def statuses(speed: int = 0, **navigation: int) -> dict[str, dict[str, Any]]:
    """Every status record of a healthy wire truck; traction reports `speed` mm/s."""
    return {
        'navigation_status': {'at_location': 0, 'slow': 0, 'reverse': 0, 'lost': 1,
                              'last_marker': 0xFF, 'speed_request': 0x40, 'sensor_lost': 0,
                              'input_fault': 0, 'stop_view': 0, **navigation},
        'traction_status': {'ref': 0, 'duty': 0, 'emergency_stop': 0, 'radio_stop': 0,
                            'tripped': 0, 'manual': 0, 'field_forward': 1, 'armature_on': 0,
                            'reversing': 0, 'source': 'executive', 'trip_cause': 'none',
                            'speed': speed},
        'route_status': {'state': 'following', 'lateral_error': 0, 'signal': 100,
                         'steering': 0, 'sign_left': 0, 'sign_right': 0, 'sign_straight': 0,
                         'manoeuvre': 0},
        'load_status': {'state': 'idle', 'cause': 'none', 'load_first': 0, 'load_second': 0,
                        'job': 0},
    }


class Executive:
    """An executive core fed healthy status records every 50 ms (and the task at its head)."""

    def __init__(self, guidance: str = 'wire') -> None:
        self.core = ExecutiveCore(ExecutiveParams(srm_map=SRM_MAP, guidance=guidance))
        self.t, self.task_id, self.out = 0.0, 0, {}
        self.head: dict[str, Any] = parse_task('status').record() | {'op': 'none'}
        self.speed = 0
        self.navigation: dict[str, int] = {}
        self.route: dict[str, Any] = {}

    def task(self, text: str) -> dict[str, Any]:
        """Hand the executive a task as communications would; return its comms_command."""
        self.task_id += 1
        self.head = parse_task(text).record() | {'task_id': self.task_id}
        return self.run(0.05)['comms_command']

    def run(self, seconds: float) -> dict[str, Any]:
        """Feed the records and tick for `seconds`; return the last commands."""
        end = self.t + seconds
        while self.t < end - 1e-9:
            self.t = round(self.t + 0.05, 6)
            records = statuses(self.speed, **self.navigation)
            records['route_status'].update(self.route)
            records['comms_status'] = self.head
            for name, fields in records.items():
                self.core.on_record(name, fields, self.t)
            self.out = self.core.tick(self.t)
        return self.out


def test_told_it_stands_at_w1_1_the_truck_leaves_by_l1_s_srm():
    ex = Executive()
    ex.run(0.2)
    report = ex.task('at 1 first')
    assert (report['state'], report['cause'], report['location']) == ('completed', 'none', 1)
    assert (ex.core.stopped_at, ex.core.stop_marker, ex.core.last_marker) == (1, 0, 1)
    assert ex.core.mode == 'idle' and ex.out['traction_command']['demand'] == 0
    out = ex.run(0.2)
    assert out['comms_command']['state'] == 'completed'  # it moved nowhere
    ex.task('stop at 3 first')
    route = ex.out['route_command']
    assert (route['mode'], route['srm_angle']) == ('srm', 15)  # on departure, as from a stop
    assert 'SRM at L1: +15 deg' in ' '.join(ex.core.notes.texts())
    assert ex.core.stopped_at is None and ex.core.stop_marker is None  # it has left


def test_not_told_the_truck_at_w1_1_follows_the_wire():
    ex = Executive()
    ex.run(0.2)
    ex.task('stop at 3 first')
    assert ex.out['route_command']['mode'] == 'follow_wire'  # to the end of W1's wire
    assert ex.out['comms_command']['location'] == 0xFF


def test_told_it_stands_at_w2_2_the_truck_follows_the_wire_on():
    ex = Executive()
    ex.run(0.2)
    report = ex.task('at 2 second')
    assert (report['state'], report['location']) == ('completed', 2)
    assert (ex.core.stopped_at, ex.core.stop_marker) == (2, 1)
    ex.task('load at 0 first')
    assert ex.out['route_command']['mode'] == 'follow_wire'  # no SRM at L2
    assert ex.run(0.2)['traction_command']['demand'] == ExecutiveParams().cruise_demand


def test_the_at_task_is_refused_while_a_task_runs_and_changes_nothing():
    ex = Executive()
    ex.run(0.2)
    ex.task('stop at 2 first')
    ex.speed = 700
    ex.run(0.5)
    assert ex.core.mode == 'running'
    steps, demand = list(ex.core.steps), ex.out['traction_command']['demand']
    report = ex.task('at 1 first')
    assert (report['state'], report['cause'], report['subsystem']) == \
        ('rejected', 'task_running', 'none')
    assert ex.core.mode == 'running' and ex.core.steps == steps
    assert ex.out['traction_command']['demand'] == demand == ExecutiveParams().cruise_demand
    assert ex.core.last_marker == 0xFF and ex.core.stopped_at is None
    assert 'at L1, stop marker 1 refused: a task is running' in ex.core.notes.texts()[-1]


def test_the_at_task_is_refused_while_the_truck_cruises_on_from_its_last_task():
    ex = Executive()
    ex.run(0.2)
    ex.task('srm at 1')  # on to L1, leave the wire there, carry on: cruising
    ex.speed = 700
    ex.run(0.5)
    ex.navigation = {'lost': 0, 'last_marker': 1}  # L1 passed: the SRM starts
    ex.run(0.2)
    ex.route = {'manoeuvre': ex.core.route['manoeuvre']}  # it has landed
    ex.run(1.0)
    assert ex.core.mode == 'cruising'
    report = ex.task('at 3 first')
    assert (report['state'], report['cause'], report['subsystem']) == \
        ('rejected', 'moving', 'traction')
    assert ex.core.mode == 'cruising' and ex.core.last_marker == 1
    assert ex.out['traction_command']['demand'] > 0


def test_the_at_task_is_refused_while_the_truck_still_rolls_and_taken_at_rest():
    ex = Executive()
    ex.speed = 400  # idle (an abort, say), still coasting to rest
    ex.run(0.2)
    report = ex.task('at 0 first')
    assert (report['state'], report['cause'], report['subsystem']) == \
        ('rejected', 'moving', 'traction')
    assert ex.core.last_marker == 0xFF and ex.core.stopped_at is None
    ex.speed = 0
    ex.run(0.2)
    report = ex.task('at 0 first')  # at rest now
    assert (report['state'], report['location']) == ('completed', 0)


def test_a_failed_truck_at_rest_is_told_where_it_was_set_down():
    ex = Executive()
    ex.run(0.2)
    ex.task('stop at 2 first')
    ex.run(0.2)
    ex.route = {'state': 'lost'}
    ex.run(0.1)
    assert ex.core.mode == 'failed'
    ex.route = {}
    ex.run(0.2)  # lifted back onto the wire, at rest
    report = ex.task('at 3 first')
    assert (report['state'], report['location']) == ('completed', 3)
    assert ex.core.mode == 'idle' and ex.core.fault is None


def test_the_camera_truck_takes_no_at_task():
    ex = Executive(guidance='camera')
    ex.run(0.2)
    report = ex.task('at 1 first')
    assert (report['state'], report['cause']) == ('rejected', 'bad_task')
    assert 'a at task, on a truck with camera guidance' in ex.core.notes.texts()[-1]


def test_the_refusal_reads_as_a_report_line():
    fields = {'task_id': 4, 'state': 'rejected', 'step': 0, 'cause': 'moving',
              'subsystem': 'traction', 'detail': 'none', 'location': 2}
    line = progress_line(4, 'at 1 first', fields)
    assert line == "task 4 'at 1 first': rejected: moving (traction) [last marker L2]"
    assert read_report(line) == Progress(4, 'at 1 first', 'rejected', None,
                                         'moving (traction)', 2)
    raw = codec()['comms_command'].encode(fields)
    assert codec()['comms_command'].decode(raw)['cause'] == 'moving'


# -- the bridge's initPosition ----------------------------------------------------------------
@pytest.fixture(scope='module')
def graph() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


def init_position(node: str, action_id: str = 'init-1') -> InstantActions:
    return InstantActions(header_id=1, timestamp=common.now(), version=VERSION,
                          manufacturer='agv_nodes', serial_number='agv1', actions=[Action(
                              action_type='initPosition', action_id=action_id,
                              blocking_type=BlockingType.HARD, action_parameters=[
                                  ActionParameter(key='lastNodeId', value=node)])])


def stop_order(ids: list[str]) -> Order:
    nodes = [Node(node_id=n, sequence_id=2 * i, released=True, actions=[])
             for i, n in enumerate(ids)]
    edges = [Edge(edge_id=f'{a}-{b}', sequence_id=2 * i + 1, released=True, start_node_id=a,
                  end_node_id=b, actions=[]) for i, (a, b) in enumerate(zip(ids, ids[1:],
                                                                            strict=False))]
    return Order(header_id=1, timestamp=common.now(), version=VERSION, manufacturer='agv_nodes',
                 serial_number='agv1', order_id='o1', order_update_id=0, nodes=nodes,
                 edges=edges)


@pytest.mark.parametrize('node, text', [('W0.1', 'at 0 first'), ('W2.1', 'at 2 first'),
                                        ('W2.2', 'at 2 second'), ('W1.1', 'at 1 first'),
                                        ('W3.1', 'at 3 first')])
def test_init_position_tells_the_truck_by_the_at_task(graph, node, text):
    flow = OrderFlow(graph)
    out = flow.on_instant_actions(init_position(node))
    assert out.tasks == [text] and out.errors == []
    assert parse_task(text).record()['op'] == 'at'
    assert flow.last_node_id == node


def test_the_at_task_pairs_with_the_truck_s_queue_and_the_order_follows_it(graph):
    flow = OrderFlow(graph)
    flow.on_instant_actions(init_position('W1.1'))
    taken = flow.on_order(stop_order(['W1.1', 'L3', 'W3.1']))  # before the truck has answered
    assert taken.verdict == 'accepted' and taken.tasks == ['stop at 3 first']
    assert not flow.task_queued(1, 'at 1 first')  # paired: no bridgeError
    assert not flow.task_queued(2, 'stop at 3 first')
    flow.task_state(1, 'completed', 0, '', 1)
    state = flow.state_fields()
    assert state['errors'] == [] and state['last_node_id'] == 'W1.1'
    # the order removed the FINISHED initPosition from the action states (6.10.6)
    assert [a.action_id for a in state['action_states']] == []
    flow.task_state(2, 'running', 0, '', 1)
    flow.task_state(2, 'running', 0, '', 3)
    flow.task_state(2, 'completed', 0, '', 3)
    assert flow.state_fields()['last_node_id'] == 'W3.1' and flow.errors == []


def test_a_refused_at_task_fails_the_init_position_and_takes_the_node_back(graph):
    flow = OrderFlow(graph)
    flow.on_instant_actions(init_position('W3.1'))
    assert not flow.task_queued(1, 'at 3 first')
    assert flow.task_state(1, 'rejected', 0, 'moving (traction)', None)  # the state changed
    assert flow.last_node_id == ''
    action = {a.action_id: a for a in flow.state_fields()['action_states']}['init-1']
    assert action.action_status == ActionStatus.FAILED
    assert 'moving (traction)' in (action.result_description or '')
    (error,) = flow.errors
    assert error.error_type == 'instantActionError'
    assert {(r.reference_key, r.reference_value) for r in error.error_references} >= {
        ('actionId', 'init-1'), ('taskId', '1')}


def test_the_bridge_sends_the_at_task_and_reads_the_truck_s_answer(graph):
    bridge = BridgeCore(graph, 'agv_nodes', 'agv1')
    out = bridge.on_message('instantActions', to_json(init_position('W2.2')), 0.0)
    assert out.tasks == ['at 2 second']
    lines = [queued_line(1, 'at 2 second', 1),
             progress_line(1, 'at 2 second', {'state': 'completed', 'step': 0, 'cause': 'none',
                                              'subsystem': 'none', 'location': 2})]
    for k, line in enumerate(lines):
        bridge.on_report(line, 1.0 + k)
    state = bridge.state()
    assert state.last_node_id == 'W2.2' and state.errors == []


# -- the whole truck in lock step ---------------------------------------------------------------
def _ends(h: Any, text: str) -> bool:
    return any(text in line and ('completed' in line or 'FAILED' in line)
               for line in h.cores['communications'].notes.texts())


def test_set_down_at_w1_1_and_told_the_truck_reaches_w3_1_by_the_srm():
    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    h = truck('demo_1983', start=at['W1.1'])
    submit(h, 'at 1 first')
    h.run(0.5)
    submit(h, 'stop at 3 first')
    assert h.run(120.0, until=lambda: _ends(h, 'stop at 3 first'))
    reports = h.cores['communications'].notes.texts()
    assert "task 1 'at 1 first': completed [last marker L1]" in reports
    assert "task 2 'stop at 3 first': completed [last marker L3]" in reports
    assert 'SRM at L1: +15 deg (manoeuvre 1)' in h.cores['executive'].notes.texts()


def test_set_down_at_w1_1_and_not_told_the_truck_runs_off_its_wire():
    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    h = truck('demo_1983', start=at['W1.1'])
    submit(h, 'stop at 3 first')
    assert h.run(60.0, until=lambda: _ends(h, 'stop at 3 first'))
    assert "task 1 'stop at 3 first': FAILED: lost wire (route)" in \
        h.cores['communications'].notes.texts()
