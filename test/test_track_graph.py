"""The track graph of a wire layout: nodes, one-way edges and routes (agv_nodes.fleet)."""

from __future__ import annotations

import math

import pytest

from agv_nodes.fleet.track_graph import TrackEdge, TrackGraph, TrackNode, track_graph
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.layout_check import route_passes

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(scope='module')
def demo() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


def test_every_location_and_stop_marker_is_a_node(demo):
    lay = load_layout(layout_path('demo_1983'))
    names = {m.name for m in lay.markers if m.kind in ('location', 'stop')}
    assert set(demo.nodes) == names == {'L0', 'L1', 'L2', 'L3', 'W0.1', 'W1.1', 'W2.1', 'W2.2',
                                        'W3.1'}
    assert [n.id for n in demo.nodes.values() if n.stoppable] == ['W0.1', 'W2.1', 'W2.2',
                                                                 'W1.1', 'W3.1']
    w22 = demo.nodes['W2.2']
    assert (w22.location, w22.conveyor, w22.station) == (2, 1, 'W2')
    assert demo.start == 'L0'  # the first card ahead of the layout's start (A at 1 m)


def test_edges_along_a_wire_are_the_distance_between_the_cards(demo):
    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    along = [e for e in demo.edges.values() if not e.srm_angle]
    assert {e.id for e in along} == {'L0-W0.1', 'W0.1-L2', 'L2-W2.1', 'W2.1-W2.2', 'W2.2-L1',
                                     'L1-W1.1', 'L3-W3.1'}
    for e in along:
        (pa, a), (pb, b) = at[e.start], at[e.end]
        assert pa == pb
        assert e.length == pytest.approx(b - a, abs=0.001), e


def test_srm_edges_land_where_the_route_map_drive_found_the_next_card(demo):
    srm = {e.id: e for e in demo.edges.values() if e.srm_angle}
    assert set(srm) == {'L1-L3', 'W1.1-L3', 'L3-L0', 'W3.1-L0'}
    assert all(e.srm_angle == 15 for e in srm.values())  # srm_map ['1:15', '3:15']
    passes = dict(route_passes(load_layout(layout_path('demo_1983')))[:7])
    assert srm['L1-L3'].length == pytest.approx(passes['L3'] - passes['L1'], abs=0.001)
    for e in (srm['L1-L3'], srm['L3-L0']):  # as driven (from a station: an estimate, below)
        a, b = demo.nodes[e.start], demo.nodes[e.end]
        # the sensor point's way, never shorter than the straight line (to the mm it weaves)
        assert e.length > math.hypot(b.x - a.x, b.y - a.y) - 0.002, e
    # leaving from the station 1.2 m after the location: the same landing, 1.2 m less to drive
    assert srm['W1.1-L3'].length == pytest.approx(srm['L1-L3'].length - 1.2, abs=0.01)
    assert srm['W3.1-L0'].length == pytest.approx(srm['L3-L0'].length - 1.2, abs=0.01)


def test_routes_follow_the_one_way_loop(demo):
    assert demo.route('W0.1', 'W3.1') == ['W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'L3', 'W3.1']
    # a station after an SRM location is a branch: a truck going on takes the SRM at once
    assert demo.route('L0', 'L3') == ['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'L3']
    assert demo.route('L0', 'L3', via_stops=True) == ['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1',
                                                      'L3']
    lap = demo.route('W1.1', 'W1.1')
    assert lap[0] == lap[-1] == 'W1.1' and len(lap) == 9
    assert demo.length(['L1', 'W1.1', 'L3']) == pytest.approx(demo.length(['L1', 'L3']))
    for a in demo.nodes:  # one loop: every node reaches every other
        for b in demo.nodes:
            assert demo.route(a, b) is not None, (a, b)


def test_an_unknown_node_has_no_route_and_a_missing_edge_no_length(demo):
    assert demo.route('L9', 'L0') is None
    assert demo.edge('L0', 'L2') is None
    with pytest.raises(ValueError, match='no edge from L0 to L2'):
        demo.length(['L0', 'L2'])


def test_a_graph_refuses_an_edge_to_a_node_it_lacks():
    node = TrackNode('L0', 'location', 0, -1, '', 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match='L0-L1'):
        TrackGraph([node], [TrackEdge('L0-L1', 'L0', 'L1', 1.0)])


@pytest.mark.parametrize('name', ['tape_1991', 'sensor_rig'])
def test_layouts_without_a_wire_route_have_no_graph(name):
    with pytest.raises(LayoutError, match='track graph'):
        track_graph(load_layout(layout_path(name)))


def test_a_wire_without_a_route_map_is_a_line():
    line = track_graph(load_layout(layout_path('straight_track')))
    assert not any(e.srm_angle for e in line.edges.values())
    assert line.route('L0', 'L3') is not None and line.route('L3', 'L0') is None


def test_agv_layout_graph_prints_the_graph_a_master_loads(capsys, demo):
    import json

    from agv_nodes.world.layout_cli import main

    assert main(['graph', 'demo_1983', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['start'] == 'L0'
    assert [n['id'] for n in doc['nodes']] == list(demo.nodes)
    assert {e['id']: e['length'] for e in doc['edges']} == {
        e.id: e.length for e in demo.edges.values()}
    assert main(['graph', 'demo_1983']) == 0
    table = capsys.readouterr().out
    assert 'L1-L3' in table and 'SRM +15 deg' in table and '-0.0' not in table
    assert main(['graph', 'tape_1991']) == 2
    assert 'no track graph' in capsys.readouterr().err
