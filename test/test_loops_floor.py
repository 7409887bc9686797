"""The two-loop floor: junctions a task chooses, the ways they open, and the tasks that drive them.

config/layouts/loops_1983.yaml is agv_nodes.world.loops_floor's floor: the house-numbered room
widened, with a crossover wire C that a truck takes at junction JA by `srm at 2 angle 15` and
leaves at CX by `srm at 2 angle -15`. The track graph learns both SRM edges from a drive; the
route map's way never takes them; the bridge turns an order across them into those tasks.
"""

from __future__ import annotations

from itertools import pairwise
import math
from pathlib import Path

import pytest
from test_task_way import order, placed

from agv_nodes.communications.task_language import parse_task
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.harness import submit, truck
from agv_nodes.package_share import config_dir
from agv_nodes.vda5050.common import Action, BlockingType
from agv_nodes.vda5050.task_way import task_way, way_tasks
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.loops_floor import loops_floor_text

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope='module')
def loops() -> TrackGraph:
    return track_graph(load_layout(layout_path('loops_1983')))


def test_the_two_loop_floor_file_is_the_modules_floor():
    file = config_dir() / 'layouts' / 'loops_1983.yaml'
    assert file.read_text() == loops_floor_text('loops_1983')


def test_the_junctions_srm_edges_are_chosen_and_the_route_map_never_takes_them(loops):
    chosen = {e.id: (e.srm_angle, loops.direction(e)) for e in loops.edges.values()
              if e.chosen}
    assert chosen == {'JA-C1': (15, 'left'), 'CX-B1': (-15, 'right')}
    assert loops.direction(loops.edges['JA-A4']) == 'straight'
    assert loops.direction(loops.edges['A3-A3.1']) is None
    assert loops.direction(loops.edges['L1-B1']) is None  # the route map's SRM: no choice
    # the crossover: wire C's markers, driven, with the wire's length between them
    assert [loops.edges[e].length for e in ('C1-C1.1', 'C1.1-CX')] == [1.2, 9.583]
    assert 8.0 < loops.edges['JA-C1'].length < 10.0  # the SRM's way, not the wire's
    assert loops.route('A3.1', 'B1.1') == ['A3.1', 'JA', 'C1', 'C1.1', 'CX', 'B1', 'B1.1']
    assert loops.route('A3.1', 'B1.1', junctions=False) == [
        'A3.1', 'JA', 'A4', 'A4.1', 'A5', 'A5.1', 'L1', 'B1', 'B1.1']
    assert loops.route('A3.1', 'C1.1', junctions=False) is None
    assert loops.route('A3.1', 'B1.1', avoid=frozenset({'C1', 'C1.1'}))[2] == 'A4'


def test_identities_alternate_on_every_way_between_stop_markers(loops):
    """The truck reports only the last location read: a repeat in a row would go unseen."""
    stops = [n for n in loops.nodes if loops.nodes[n].stoppable]
    for a in stops:
        for b in stops:
            way = task_way(loops, a, True, b)
            assert way is not None and way_tasks(loops, way, True) is not None, (a, b)
            ids = [loops.nodes[n].location for n in way if loops.nodes[n].kind == 'location']
            assert all(x != y for x, y in pairwise(ids)), (a, b, way)


def test_the_tasks_of_a_way_across_the_junctions(loops):
    way = task_way(loops, 'A1.1', True, 'B3.1')
    assert way == ['A1.1', 'A2', 'A2.1', 'A3', 'A3.1', 'JA', 'C1', 'C1.1', 'CX', 'B1', 'B1.1',
                   'B2', 'B2.1', 'B3', 'B3.1']  # the small loop: shorter
    assert way_tasks(loops, way, True) == [
        (1, 'pass 2'), (5, 'srm at 2 angle 15'), (8, 'srm at 2 angle -15'), (9, 'pass 0')]
    for _, text in way_tasks(loops, way, True):
        parse_task(text)
    # from a stop of the junction's own location `srm at 2` would leave at once: a pass first
    lap = task_way(loops, 'A2.1', True, 'A2.1')
    assert lap[:4] == ['A2.1', 'A3', 'A3.1', 'JA'] and lap[4] == 'C1'
    assert way_tasks(loops, lap, True)[:2] == [(1, 'pass 0'), (3, 'srm at 2 angle 15')]
    # a way the tasks cannot drive: C1 straight on from JA (no such edge), or off the wire
    assert way_tasks(loops, ['A3.1', 'JA', 'A4', 'C1'], True) is None
    # past the junction there is one way on: round the big loop
    assert task_way(loops, 'A4.1', True, 'B1.1') == ['A4.1', 'A5', 'A5.1', 'L1', 'B1', 'B1.1']


@pytest.mark.parametrize('entry, words', [
    ("['J9:15']", "'J9:15' is not 'NAME:angle'"),
    ("['JA:0']", "'JA:0' is not"),
    ("['L1:15']", "'L1:15' is not"),  # the route map's location: it always leaves there
    ("'JA:15'", 'must be a list'),
])
def test_a_bad_junction_is_refused_naming_the_file_and_key(tmp_path: Path, entry: str,
                                                           words: str):
    text = loops_floor_text('bad').replace("junctions: ['JA:15', 'CX:-15']",
                                           f'junctions: {entry}')
    file = tmp_path / 'bad.yaml'
    file.write_text(text)
    with pytest.raises(LayoutError, match=words) as caught:
        load_layout(file)
    assert str(file) in str(caught.value) and 'key junctions' in str(caught.value)
    assert '\n' not in str(caught.value)


def test_a_truck_crosses_by_its_tasks_and_stops_on_wire_c_then_on_b(loops):
    """The whole truck in lock step: the junction's SRM, C1.1, the exit's SRM, B1.1."""
    lay = load_layout(layout_path('loops_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    h = truck('loops_1983', start=at['A3.1'])
    submit(h, 'at 0 first')
    h.run(0.5)
    for text in ('srm at 2 angle 15', 'stop at 0 first', 'srm at 2 angle -15',
                 'stop at 0 first'):
        submit(h, text)
    wheelbase = h.world.p.electruk.wheelbase
    stops = []

    def done() -> bool:
        texts = h.cores['communications'].notes.texts()
        if len(stops) < sum("'stop at 0 first': completed" in t for t in texts):
            x, y, heading, _ = h.world.pose()
            stops.append((x, y, heading))
        return len(stops) == 2 or any('FAILED' in t for t in texts)

    assert h.run(240.0, until=done)
    reports = h.cores['communications'].notes.texts()
    assert not any('FAILED' in t for t in reports), reports
    for (x, y, heading), node in zip(stops, ('C1.1', 'B1.1'), strict=True):
        target = loops.nodes[node]
        # the pose is the rear axle's: the sensor point is a wheelbase ahead of it
        sx, sy = x + wheelbase * math.cos(heading), y + wheelbase * math.sin(heading)
        assert abs(sx - target.x) < 0.1 and abs(sy - target.y) < 0.1, (node, sx, sy, target)


def test_the_bridge_turns_an_order_across_the_junctions_into_srm_tasks(loops):
    flow = placed(loops, 'A3.1')
    ids = task_way(loops, 'A3.1', True, 'B2.1')
    drop = Action(action_id='d', action_type='drop', blocking_type=BlockingType.HARD)
    out = flow.on_order(order(ids, {'B2.1': drop}))
    assert out.verdict == 'accepted', out.errors
    assert out.tasks == ['srm at 2 angle 15', 'srm at 2 angle -15', 'unload at 2 first']
    # the truck reports identities; the bridge follows it across: JA, C1, CX, B1, B2
    flow.task_queued(1, out.tasks[0])
    flow.task_queued(2, out.tasks[1])
    flow.task_queued(3, out.tasks[2])
    flow.task_state(1, 'running', 0, '', 2)
    assert flow.last_node_id == 'JA'
    flow.task_state(1, 'completed', 0, '', 2)
    flow.task_state(2, 'running', 0, '', 0)
    assert flow.last_node_id == 'C1'
    flow.task_state(2, 'running', 0, '', 2)
    assert flow.last_node_id == 'CX'
    flow.task_state(2, 'completed', 0, '', 2)
    flow.task_state(3, 'running', 0, '', 0)
    assert flow.last_node_id == 'B1'
    flow.task_state(3, 'running', 0, '', 2)
    assert flow.last_node_id == 'B2'


def test_an_edge_direction_against_the_junction_is_an_order_error(loops):
    flow = placed(loops, 'A3.1')
    ids = task_way(loops, 'A3.1', True, 'C1.1')
    message = order(ids, {})
    message.edges[1].direction = 'left'  # JA-C1: the junction's SRM, left
    assert flow.on_order(message).verdict == 'accepted'
    flow = placed(loops, 'A3.1')
    message = order(ids, {})
    message.edges[1].direction = 'straight'
    out = flow.on_order(message)
    assert out.verdict == 'rejected'
    [error] = out.errors
    assert error.error_type == 'orderError'
    assert "direction 'straight', but at junction JA that edge goes 'left'" in \
        error.error_description
    refs = {r.reference_key: r.reference_value for r in error.error_references}
    assert refs['edgeId'] == 'JA-C1' and refs['direction'] == 'straight'
