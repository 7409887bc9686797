"""The fleet's floor: house-numbered locations (Baker 1983, 8.5) and what a layout may repeat.

config/layouts/fleet_1983.yaml is agv_nodes.world.fleet_floor's floor for eight trucks; the
layout loader refuses names and identities the truck or its central computer could not tell
apart, each with one line naming the file, the key and the value.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from agv_nodes.fleet.blocks import default_blocks
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.package_share import config_dir
from agv_nodes.world.fleet_floor import (
    DEMO_LOADS,
    EXTENSION,
    FLEET_TRUCKS,
    extension_for,
    fleet_floor_text,
    programme_loads,
)
from agv_nodes.world.layout import LayoutError, layout_path, load_layout

pytestmark = pytest.mark.timeout(300)


def test_the_fleet_floor_file_is_the_modules_floor_for_eight_trucks():
    file = config_dir() / 'layouts' / 'fleet_1983.yaml'
    assert file.read_text() == fleet_floor_text('fleet_1983', EXTENSION, FLEET_TRUCKS)


def test_the_fleet_floor_parks_eight_trucks_a_block_apart():
    lay = load_layout(layout_path('fleet_1983'))
    graph = track_graph(lay)
    blocks = {b.name: b.nodes for b in default_blocks(graph)}
    assert len(blocks) == 18  # 16 houses, L1 and L3
    assert lay.parking == ('A1.1', 'A3.1', 'A5.1', 'A7.1', 'B1.1', 'B3.1', 'B5.1', 'B7.1')
    parked = [next(name for name, nodes in blocks.items() if stop in nodes)
              for stop in lay.parking]
    assert parked == ['A1', 'A3', 'A5', 'A7', 'B1', 'B3', 'B5', 'B7']
    # identities alternate along each street; the route map's locations are unique
    houses = [n for n in graph.nodes.values() if n.kind == 'location']
    assert [n.location for n in houses if n.id.startswith('A')] == [0, 2] * 4
    assert [n.location for n in houses if n.id.startswith('B')] == [0, 2] * 4
    assert [n.id for n in houses if n.location in (1, 3)] == ['L1', 'L3']
    assert graph.nodes['A3.1'].location_marker == 'A3'
    assert graph.nodes['A3.1'].location == 0


def test_larger_floors_park_their_fleets_and_their_check_passes(tmp_path: Path):
    assert extension_for(FLEET_TRUCKS) == EXTENSION
    extension = extension_for(32)
    file = tmp_path / 'fleet_n32.yaml'
    file.write_text(fleet_floor_text('fleet_n32', extension, 32))
    lay = load_layout(file)
    assert len(lay.parking) == 32
    graph = track_graph(lay)  # drives the route map: every SRM lands, houses in order
    assert len(default_blocks(graph)) >= 33
    with pytest.raises(ValueError, match='33 trucks'):
        fleet_floor_text('x', extension, 33)


def test_a_programme_sends_a_load_per_truck_on_the_fleet_floor_and_two_on_the_demo():
    fleet = load_layout(layout_path('fleet_1983')).stations
    assert programme_loads(fleet, 3) == {'load1': ('A1', 'B1'), 'load2': ('A2', 'B2'),
                                         'load3': ('A3', 'B3')}
    assert all(fleet[a].has_load and not fleet[b].has_load
               for a, b in programme_loads(fleet, 8).values())
    assert programme_loads(load_layout(layout_path('demo_1983')).stations, 3) == DEMO_LOADS
    with pytest.raises(ValueError, match='W0, W1, W2, W3'):
        programme_loads(['A1', 'B1'], 2)


def write(tmp_path: Path, name: str, markers: list[str], srm_map: str = '[]') -> Path:
    """Write a one-wire layout 20 m long with `markers` (YAML flow mappings)."""
    file = tmp_path / f'{name}.yaml'
    file.write_text(f'layout: {name}\nvehicle: electruk\nkind: wire\n'
                    'wires:\n  - id: A\n    start: [0.0, 0.0, 0.0]\n'
                    '    segments: [{straight: 20.0}]\n'
                    'stations:\n  - {id: S, has_load: false, capacity: 1}\n'
                    'markers:\n' + ''.join(f'  - {m}\n' for m in markers)
                    + f'start: {{path: A, at: 0.5}}\nsrm_map: {srm_map}\n')
    return file


@pytest.mark.parametrize(('markers', 'srm_map', 'message'), [
    (['{kind: location, identity: 0, path: A, at: 3.0}',
      '{kind: location, identity: 0, path: A, at: 9.0}'], '[]',
     r"key markers\[1\].name: 'L0' is markers\[0\] too"),
    (['{kind: location, identity: 0, name: H1, path: A, at: 3.0}',
      '{kind: location, identity: 2, name: H1, path: A, at: 9.0}'], '[]',
     r"key markers\[1\].name: 'H1' is markers\[0\] too"),
    (['{kind: location, identity: 1, name: H1, path: A, at: 3.0}',
      '{kind: location, identity: 1, name: H2, path: A, at: 9.0}'], "['1:15']",
     r"key srm_map: '1:15': location 1 is markers \[0, 1\]"),
    (['{kind: location, identity: 0, path: A, at: 3.0}',
      '{kind: stop, station: S, name: H1, path: A, at: 4.2}'], '[]',
     r"key markers\[1\].name: 'H1': only a location marker is named"),
    (['{kind: location, identity: 0, name: 1A, path: A, at: 3.0}'], '[]',
     r"key markers\[0\].name: '1A'"),
    (['{kind: location, identity: 0, path: A, at: 3.0, colour: red}'], '[]',
     r'key markers\[0\].colour: unknown'),
])
def test_names_and_identities_the_floor_cannot_tell_apart_are_refused(tmp_path, markers,
                                                                      srm_map, message):
    file = write(tmp_path, 'bad', markers, srm_map)
    with pytest.raises(LayoutError, match=message) as caught:
        load_layout(file)
    text = str(caught.value)
    assert text.startswith(f'{file}: key ') and '\n' not in text


def test_one_identity_at_two_locations_in_a_row_has_no_track_graph(tmp_path):
    file = write(tmp_path, 'twice', [
        '{kind: location, identity: 0, name: H1, path: A, at: 3.0}',
        '{kind: stop, station: S, path: A, at: 4.2}',
        '{kind: location, identity: 0, name: H2, path: A, at: 9.0}'])
    lay = load_layout(file)  # the cards are readable; the truck could not report the second
    with pytest.raises(LayoutError, match='H1 and H2 .both identity 0. follow each other'):
        track_graph(lay)
    ok = write(tmp_path, 'apart', [
        '{kind: location, identity: 0, name: H1, path: A, at: 3.0}',
        '{kind: stop, station: S, path: A, at: 4.2}',
        '{kind: location, identity: 2, name: H2, path: A, at: 9.0}',
        '{kind: location, identity: 0, name: H3, path: A, at: 15.0}'])
    graph = track_graph(load_layout(ok))
    assert [n.id for n in graph.nodes.values() if n.kind == 'location'] == ['H1', 'H2', 'H3']
    assert graph.nodes['S.1'].location_marker == 'H1'
