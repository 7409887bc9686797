"""What agv-launch --trucks N starts, and what it refuses, without starting anything."""

from __future__ import annotations

import pytest

from agv_nodes.graph.model import GraphError, load_graph
from agv_nodes.graph.parameters import (
    Options,
    check_fleet,
    floor_parameters,
    node_parameters,
    truck_graph,
)
from agv_nodes.graph.supervisor import Launch


@pytest.mark.parametrize('options, words', [
    (Options(trucks=4), "layout 'demo_1983' parking names 3 stop markers (W2.2, W0.1, W1.1)"),
    (Options(trucks=9, layout='fleet_1983'), "layout 'fleet_1983' parking names 8 stop markers"),
    (Options(trucks=2, set_down=['W2.2']), '--set-down names 1 stop markers'),
    (Options(trucks=1, set_down=['L0']), "no stop marker 'L0' in layout 'demo_1983'"),
    (Options(trucks=2, namespace='/x'), 'with --namespace'),
    (Options(trucks=2, world='none'), 'with --world none'),
    (Options(trucks=33), '1-32'),
    (Options(trucks=1, layout='tape_1991'), 'not a wire layout of the Electruk'),
    (Options(set_down=['W0.1']), 'add --trucks N'),
    (Options(trucks=2, external_master=True), 'add --trucks N --vda5050'),
])
def test_a_fleet_the_launch_cannot_run_is_refused_before_anything_starts(options, words):
    graph = truck_graph(load_graph(), options)
    with pytest.raises(GraphError) as err:
        check_fleet(graph, options)
    assert words in str(err.value)


def test_each_truck_s_nodes_run_in_its_namespace_and_the_world_once_for_the_floor():
    launch = Launch(Options(trucks=2, quiet=True, domain_id=99, vda5050=True,
                            mqtt_url='mqtt://127.0.0.1:1'))
    try:
        units = launch.units()
        labels = [label for label, _spec, _ns in units]
        assert labels[-2:] == ['dispatcher', 'world']  # the master and the world once, last
        per_truck = [s.name for s in launch.specs() if s.role in ('node', 'bridge')]
        assert labels[:-2] == [f'{t}/{n}' for t in ('agv1', 'agv2') for n in per_truck]
        assert {ns for label, _s, ns in units if '/' in label} == {'/agv1', '/agv2'}
        assert [ns for label, _s, ns in units if '/' not in label] == ['', '']
        command = launch.command(*next(u[1:] for u in units if u[0] == 'agv2/traction'),
                                 label='agv2/traction')
        assert '__ns:=/agv2' in command
        master = node_parameters(launch.graph, launch.graph.node('dispatcher'), launch.o)
        assert master['trucks'] == ['agv1', 'agv2']
        assert master['positions'] == ['agv1:W2.2', 'agv2:W0.1'] == master['parking']
    finally:
        launch.stop()


def test_eight_trucks_launch_on_the_fleet_floor_each_at_its_parking_place():
    options = Options(trucks=8, layout='fleet_1983', quiet=True, domain_id=99, vda5050=True,
                      mqtt_url='mqtt://127.0.0.1:1')
    check_fleet(truck_graph(load_graph(), options), options)
    launch = Launch(options)
    try:
        master = node_parameters(launch.graph, launch.graph.node('dispatcher'), launch.o)
        assert master['trucks'] == [f'agv{k}' for k in range(1, 9)]
        assert master['positions'] == ['agv1:A1.1', 'agv2:A3.1', 'agv3:A5.1', 'agv4:A7.1',
                                       'agv5:B1.1', 'agv6:B3.1', 'agv7:B5.1', 'agv8:B7.1']
        assert master['layout'] == 'fleet_1983'
    finally:
        launch.stop()


@pytest.mark.parametrize('recording', [False, True])
def test_the_floor_waits_for_clock_readers_of_every_truck_and_each_world_for_its_truck(
        tmp_path, recording):
    options = Options(trucks=3, set_down=['W2.2', 'W0.1', 'W3.1'],
                      bag=tmp_path / 'bag' if recording else None)
    graph = truck_graph(load_graph(), options)
    out = floor_parameters(graph, graph.node('world'), options)
    assert sorted(out) == ['/agv1/world', '/agv2/world', '/agv3/world', '/world']
    paced = len(out['/world']['ros__parameters']['pace_nodes'])  # one truck's seven nodes
    root = out['/world']['ros__parameters']['wait_for_links']
    assert f'world>clock:{3 * paced + recording}' in root
    assert ('recorder:clock' in root) == recording
    truck = out['/agv2/world']['ros__parameters']
    assert truck['trucks'] == ['agv1', 'agv2', 'agv3']
    assert truck['set_down'] == ['W2.2', 'W0.1', 'W3.1']
    assert not [link for link in truck['wait_for_links'] if 'clock' in link]
    assert 'traction:traction_drive' not in truck['wait_for_links']  # the world writes it
    assert 'world:traction_drive' in truck['wait_for_links']


@pytest.mark.parametrize('argv, words', [
    (['--layout', 'fleet_1983'], '--layout are for a fleet: add --fleet N'),
    (['--transfers', '2'], 'are for a fleet: add --fleet N'),
    (['--fleet', '2', '--truck', 'concic2'], '--fleet runs the 1983 truck'),
])
def test_agv_demo_refuses_fleet_options_without_a_fleet(capsys, argv, words):
    from agv_nodes.demo import main

    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    assert words in capsys.readouterr().err


def test_agv_demo_refuses_a_fleet_the_floor_cannot_park_before_anything_starts(capsys, tmp_path):
    from agv_nodes.demo import main

    assert main(['--fleet', '9', '--layout', 'fleet_1983', '--out', str(tmp_path)]) == 2
    assert "layout 'fleet_1983' parking names 8 stop markers" in capsys.readouterr().err
