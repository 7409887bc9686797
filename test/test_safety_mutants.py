"""Safety tests that bench/mutation_bench.py found missing: each catches a surviving mutation.

Expected values come from outside the code under test: the record tables (msg_schemas/, the
CRC-8/SAE-J1850 of docs/records.md) and the declared parameter values (parameters.yaml).
"""

from __future__ import annotations

import pytest

from agv_nodes.clock_jump import Jump
from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.harness import submit, truck
from agv_nodes.records import RecordReader, RecordWriter, codec
from agv_nodes.records.compiled_paths import compiled_port_paths
from agv_nodes.records.fast_paths import compile_port_paths
from agv_nodes.traction.core import TractionCore
from agv_nodes.traction.settings import TractionParams
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.order import Edge, Node, Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.world.layout import layout_path, load_layout

PROTECTED = [s for s in codec() if s.protected]


def _fast_check(schema, path: str):
    """Return the reader's fast path: the C codec's check, or the generated Python one."""
    if path == 'python':
        return compile_port_paths(schema, 'e2e')[1]
    paths = compiled_port_paths(schema, 'e2e')
    if paths is None:
        pytest.skip('the C codec is not built here (its Python stand-in is the other case)')
    return paths[1]


@pytest.mark.timeout(60)
@pytest.mark.parametrize('path', ['c', 'python'])
@pytest.mark.parametrize('schema', PROTECTED, ids=lambda s: s.name)
def test_a_port_rejects_any_single_byte_corruption_of_a_new_record_as_bad_crc(schema, path):
    """A corrupt record whose counter is new (not a repeat) is refused for its CRC.

    Through the reader's fast path, where a corrupt copy of the last record would be refused
    for its repeated counter anyway: here the record corrupted is the next one, which the
    reader would accept, and after every corruption of it the genuine one still is.
    """
    writer, reader = RecordWriter(schema), RecordReader(schema)
    reader.fast_decode = _fast_check(schema, path)
    assert reader.accept(writer.pack({}), 0) is not None
    genuine = writer.pack({})
    corruptions = 0
    for byte in range(16):
        for bits in range(1, 256):  # CRC-8 catches every burst within one byte
            bad = bytearray(genuine)
            bad[byte] ^= bits
            assert reader.accept(bytes(bad), 1) is None, (byte, bits)
            corruptions += 1
    assert reader.rejects == {'bad_crc': corruptions}
    assert reader.accept(genuine, 2) is not None and reader.accepted == 2


# -- traction: the bumper in the program's own cut (GETREF), as the radio stop ----------------
def _traction_run(core: TractionCore, demand: int, t: float, seconds: float) -> tuple[float, dict]:
    """Tick `core` every 10 ms for `seconds`, the executive's command every 50 ms."""
    drive: dict = {}
    for k in range(round(seconds / 0.01)):
        now = round(t + k * 0.01, 6)
        if k % 5 == 0:
            core.on_record('traction_command', {'manual': 0, 'manual_speed': 0, 'reverse': 0,
                                                'demand': demand, 'executive_priority': 0}, now)
        drive = core.tick(now)['traction_drive']
    return round(t + seconds, 6), drive


@pytest.mark.timeout(30)
@pytest.mark.parametrize('control', ['open_loop_1983', 'closed_loop'])
def test_a_pressed_bumper_cuts_tractions_armature_in_auto_mode(control):
    """Baker 1983, App. B.2.2's GETREF: the stop switch cuts the armature and re-polls.

    The bumper is wired as the radio stop (traction/core.py's on_bumper): a truck under way
    in auto mode has its armature off and duty 0 within a pass, reported as `bumper`, not as
    the operator's radio stop; released, the same demand drives it again.
    """
    core = TractionCore(TractionParams(control=control))
    t, _ = _traction_run(core, 0, 0.0, 0.1)  # the start-up latch: 00H, then a demand
    t, drive = _traction_run(core, 30, t, 2.0)
    assert drive['armature_enable'] == 1 and drive['armature_duty'] > 0
    core.on_bumper(True, t)
    t, drive = _traction_run(core, 30, t, 0.02)
    assert drive['armature_enable'] == 0 and drive['armature_duty'] == 0 and core.dcycle == 0
    status = core.status()
    assert (status['bumper'], status['radio_stop'], status['source']) == (1, 0, 'bumper')
    assert not core.tripped  # a switch, not a fault of traction: no latch to reset
    core.on_bumper(False, t)
    t, drive = _traction_run(core, 30, t, 2.0)
    assert drive['armature_enable'] == 1 and drive['armature_duty'] > 0


# -- the VDA 5050 bridge: an order whose edges do not join all its nodes -----------------------
def _order(ids: list[str]) -> Order:
    """Return an order along `ids`: all released, sequenceIds from 0."""
    nodes = [Node(node_id=n, sequence_id=2 * i, released=True, actions=[])
             for i, n in enumerate(ids)]
    pairs = zip(ids, ids[1:], strict=False)
    edges = [Edge(edge_id=f'{a}-{b}', sequence_id=2 * i + 1, released=True, start_node_id=a,
                  end_node_id=b, actions=[]) for i, (a, b) in enumerate(pairs)]
    return Order(header_id=1, timestamp=common.now(), version=VERSION, manufacturer='m',
                 serial_number='s', order_id='o1', order_update_id=0, nodes=nodes, edges=edges)


@pytest.mark.timeout(60)
def test_an_order_missing_its_last_edge_is_an_order_error_and_no_task():
    """VDA 5050 2.1, 6.6.1: an order of n nodes has n - 1 edges, one between each two.

    Without its last edge the order's last node is joined to nothing; the truck must not be
    sent there. The same order whole is accepted (the check can fail).
    """
    graph = track_graph(load_layout(layout_path('demo_1983')))
    ids = ['L0', 'W0.1', 'L2', 'W2.1']  # demo_1983's loop from its start to a stop marker
    assert OrderFlow(graph).on_order(_order(ids)).verdict == 'accepted'
    order = _order(ids)
    order.edges.pop()
    out = OrderFlow(graph).on_order(order)
    assert out.verdict == 'rejected' and out.tasks == []
    assert [e.error_type for e in out.errors] == ['orderError']


@pytest.mark.timeout(60)
@pytest.mark.parametrize('sequence_id', [3, 6, 8])
def test_a_node_sequence_id_out_of_step_either_way_is_an_order_error(sequence_id):
    """VDA 5050 2.1, 6.6.2: nodes and edges alternate with consecutive sequenceIds.

    The third node of an order from 0 is 4; one below or one that skips ahead is refused,
    naming the node and its sequenceId.
    """
    graph = track_graph(load_layout(layout_path('demo_1983')))
    order = _order(['L0', 'W0.1', 'L2', 'W2.1'])
    order.nodes[2].sequence_id = sequence_id
    out = OrderFlow(graph).on_order(order)
    assert out.verdict == 'rejected' and out.tasks == []
    named = [{r.reference_key: r.reference_value for r in e.error_references or ()}
             for e in out.errors]
    assert {'nodeId': 'L2', 'sequenceId': str(sequence_id)}.items() <= named[0].items()


# -- task bounds: a number past what its record field holds ------------------------------------
@pytest.mark.timeout(30)
def test_a_dwell_past_its_record_byte_is_refused_naming_the_column():
    """comms_status's dwell is one unsigned byte (msg_schemas/comms_status.yaml): 0..255 s.

    A wait of one second more is refused with the column of the number, never wrapped or
    clipped into the byte; the largest that fits is taken as given.
    """
    most = codec()['comms_status'].field('dwell').hi
    assert parse_task(f'wait at 0 for {most} s then continue').record()['dwell'] == most
    text = f'wait at 0 for {most + 1} s then continue'
    with pytest.raises(TaskError) as info:
        parse_task(text)
    assert info.value.column == text.index(str(most + 1)) + 1
    assert f'outside 0..{most}' in str(info.value)


# -- the executive's own reaction to a /clock jump --------------------------------------------
@pytest.mark.timeout(120)
def test_a_clock_jump_told_to_the_executive_alone_fails_the_task_and_stops_the_truck():
    """Each node's /clock reader tells its own core (core_node): traction may not have seen it.

    The executive alone takes the jump while the truck cruises: it fails the task naming the
    clock (comms_command's cause clock_jumped, msg_schemas/comms_command.yaml) and stops the
    truck with its own 00H, traction's relay still closed.
    """
    h = truck()
    submit(h, 'stop at 2 second')
    assert h.run(30.0, until=lambda: h.world.pose()[3] > 0.6), 'the truck never cruised'
    executive = next(m for m in h.members if m.core is h.cores['executive'])
    jump = Jump(round(h.now * 1e9), round((h.now - 5.0) * 1e9))
    h._publish(executive, executive.core.on_clock_jump(jump.text(), h.now))
    h.run(5.0)
    assert h.cores['executive'].fault == ('clock_jumped', 'world')
    assert h.cores['communications'].results == [(1, 'failed', 'clock_jumped')]
    assert h.world.pose()[3] == 0.0
    assert not h.cores['traction'].tripped  # the executive's 00H stopped it, not the relay


# -- the positioning limit: where the truck stops when its stop marker is missing -------------
@pytest.mark.timeout(120)
def test_a_missing_stop_marker_fails_the_task_at_the_positioning_limit_not_later():
    """The executive's positioning_limit (its parameters.yaml) bounds the overrun itself.

    route_limit gives the same fault (route_limit, navigation) much later, so the fault alone
    does not show which limit acted: here the ground-truth travel from the start of
    positioning to the fault is the limit, give or take two passes of the executive at the
    truck's speed and 5 mm of its odometry, and the truck then rests within 0.1 m of it.
    """
    params = ExecutiveParams()
    limit, period = params.positioning_limit, params.period
    h = truck('straight_track', seed=2)
    h.world.layout.markers = [m for m in h.world.layout.markers if m.station != 'S1']
    submit(h, 'stop at 1 first')
    ex, state = h.cores['executive'], h.world.vehicle.state
    start = None
    while h.now < 200 and ex.mode == 'running':
        h.step()
        if start is None and ex.phase == 'positioning':
            start = state.distance
    assert start is not None and ex.fault == ('route_limit', 'navigation')
    overrun = state.distance - start
    assert -0.005 <= overrun - limit <= 2 * period * abs(state.speed) + 0.005, overrun
    h.run(5.0)
    assert state.speed == 0.0 and state.distance - start <= limit + 0.1


# -- duplicate writers: the cores' own reactions (over DDS: test_duplicate_writer_dds.py) ------
@pytest.mark.timeout(30)
def test_a_duplicate_writer_of_the_command_opens_tractions_relay_at_once():
    """Two live executives (records.writer_check): traction trusts neither and trips now.

    Its answer to the rejection is a traction_drive record with the contactor open, not one
    at the next pass, and the trip cause is traction_status's `duplicate_writer`
    (msg_schemas/traction_status.yaml), not a stale command later.
    """
    trip_causes = codec()['traction_status'].field('trip_cause').values
    assert 'duplicate_writer' in trip_causes
    core = TractionCore(TractionParams())
    t, _ = _traction_run(core, 0, 0.0, 0.1)
    t, drive = _traction_run(core, 30, t, 2.0)
    assert drive['contactor'] == 1 and drive['armature_duty'] > 0
    out = core.on_reject('traction_command', 'duplicate_writer', t)
    assert out is not None and out['traction_drive']['contactor'] == 0
    assert out['traction_drive']['armature_enable'] == 0
    assert core.status()['trip_cause'] == 'duplicate_writer'


@pytest.mark.timeout(120)
def test_a_duplicate_writer_of_a_status_fails_the_task_naming_it_and_stops_the_truck():
    """The executive told of two live writers of navigation's status fails the task at once.

    comms_command's cause `duplicate_writer` (msg_schemas/comms_command.yaml), naming the
    sub-system, while the status itself still arrives: not a stale status later.
    """
    h = truck()
    submit(h, 'stop at 2 second')
    assert h.run(30.0, until=lambda: h.world.pose()[3] > 0.6), 'the truck never cruised'
    executive = next(m for m in h.members if m.core is h.cores['executive'])
    out = executive.core.on_duplicate_writer('navigation_status', h.now)
    assert out is not None and out['traction_command']['demand'] == 0
    h._publish(executive, out)
    h.run(5.0)
    assert h.cores['executive'].fault == ('duplicate_writer', 'navigation')
    assert h.cores['communications'].results == [(1, 'failed', 'duplicate_writer')]
    assert h.world.pose()[3] == 0.0


# -- the executive: every sub-system silent at once (no arrival to confirm a stale status) ----
@pytest.mark.timeout(120)
def test_a_whole_silent_truck_is_a_stale_status_at_twice_status_timeout():
    """stale_confirm waits for the others' records; with none coming, age alone decides.

    The executive's parameters.yaml: "at twice status_timeout age alone does". The truck
    cruises in lock step, then the executive alone runs on (its loop every `period`, its
    supervision every `supervision_period`) and hears nothing more: the task fails as a stale
    status within twice status_timeout and one supervision period of the last record.
    """
    p = ExecutiveParams()
    h = truck()
    submit(h, 'stop at 2 second')
    assert h.run(30.0, until=lambda: h.world.pose()[3] > 0.6), 'the truck never cruised'
    ex, last = h.cores['executive'], h.now
    t, k, out = last, 0, None
    while ex.fault is None and k < 1000:
        k += 1
        t = round(last + k * p.supervision_period, 6)
        if k % round(p.period / p.supervision_period) == 0:
            out = ex.tick(t)
        out = ex.supervise(t) or out
    assert ex.fault is not None and ex.fault[0] == 'stale_status'
    assert t - last <= 2 * p.status_timeout + p.supervision_period + 1e-9, t - last
    assert out is not None and out['traction_command']['demand'] == 0
