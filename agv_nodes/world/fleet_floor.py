"""A fleet's floor: the demonstration room of Baker 1983, 7.2, lengthened, its locations numbered.

demo_1983 has four location markers, one per identity of the 2-bit card (Baker 1983, 4.4),
so a block per location leaves room for three trucks. The thesis saw the limit (8.5) and
proposed maps: locations addressed like house numbers along a street, fewer distinct markers,
the complexity moved into the controller's stored map and history-based decisions. This floor
does that. It keeps the room's two wires and its route map (SRM 1 at L1 off wire A, SRM 2 at
L3 off wire B, both 15 degrees left) and lengthens the room by `extension` m. Along the
lengthened legs (A's south leg eastwards, B's north leg westwards) stand house-numbered
locations: A1, A2, ... and B1, B2, ..., their identities alternating 0 and 2, each with a
workstation of the same name whose stop marker (A1.1) stands `STOP_AFTER` m after it. The
truck still reads only the identity; the central computer tells A1 from A3 by the way the
truck came (agv_nodes.fleet.track_graph, agv_nodes.vda5050.task_way).

Stations: W1 and W3 are the room's branches after the SRM locations, where a truck stands off
the loop's way (passing places); the A stations start with a load, the B stations are empty.
A truck is parked at every other house-numbered station from A1 on, so parked trucks leave a
block free between them.

`config/layouts/fleet_1983.yaml` is this module's floor for eight trucks (its `extension`,
`FLEET_EXTENSION`); a test holds the file equal to it. Benchmarks of larger fleets write longer
floors from here.
"""

from __future__ import annotations

from collections.abc import Iterable
import math

EXTENSION = 21.0  # m added to each straight of demo_1983: eight houses per leg
FLEET_TRUCKS = 8  # the parking places of config/layouts/fleet_1983.yaml
PITCH = 3.5  # m from one house to the next: a stop marker, a truck's length and a margin
STOP_AFTER = 1.2  # m from a location marker to its stop marker (Baker 1983, 6.3.2: >= 1 m)
ARC = 2.5  # m, the room's end radius
A_FIRST = 6.5  # m along A: the first house after SRM 2 lands (demo_1983's L0)
B_FIRST = 4.5  # m along B: the first house after SRM 1 lands
END_CLEARANCE = 2.9  # m from a house to the end of its straight (its stop and a truck's nose)


def houses(straight: float, first: float) -> list[float]:
    """Return the places along a leg of `straight` m where houses stand, from `first` on."""
    count = int((straight - END_CLEARANCE - first) // PITCH) + 1
    return [round(first + k * PITCH, 3) for k in range(max(count, 0))]


def room_wires(extension: float, arc: float, width: float) -> list[str]:
    """Return the room's wires A and B, lengthened by `extension` m, ends of radius `arc`.

    A's south leg runs east along y = 0 and turns left to run back west 1 m outside B (its
    spur, after L1); B's north leg runs west along y = `width` and turns left to run back east
    1 m outside A (after L3): the demonstration room's plan (Baker 1983, fig 7.14).
    """
    return [
        'wires:',
        '  - id: A',
        '    start: [-3.0, 0.0, 0.0]',
        '    segments:',
        f'      - straight: {13.0 + extension:g}',
        f'      - {{arc: {arc:g}, angle: 180}}',
        '      - straight: 4.0',
        '  - id: B',
        f'    start: [{7.0 + extension:g}, {width:.1f}, 180.0]',
        '    segments:',
        f'      - straight: {11.0 + extension:g}',
        f'      - {{arc: {arc:g}, angle: 180}}',
        '      - straight: 5.0']


def house_stations(names: list[tuple[str, str, float]]) -> list[str]:
    """Return the stations of the houses (name, wire, at): A's with a load, B's empty."""
    return [f'  - {{id: {house}, has_load: {"true" if wire == "A" else "false"}, capacity: 1}}'
            for house, wire, _ in names]


def house_markers(house: str, wire: str, at: float, identity: int) -> list[str]:
    """Return a house's location marker and, STOP_AFTER m on, its workstation's stop marker."""
    return [f'  - {{kind: location, identity: {identity}, name: {house}, path: {wire}, '
            f'at: {at:g}}}',
            f'  - {{kind: stop, station: {house}, path: {wire}, at: {at + STOP_AFTER:g}}}']


def route_map_markers(extension: float, arc: float) -> list[str]:
    """Return L1 and W1, L3 and W3 (1.5 m into each spur), the start and the route map."""
    half = math.pi * arc  # an end's half circle
    l1 = round(13.0 + extension + half + 1.5, 3)
    l3 = round(11.0 + extension + half + 1.5, 3)
    return [f'  - {{kind: location, identity: 1, path: A, at: {l1:g}}}',
            f'  - {{kind: stop, station: W1, path: A, at: {l1 + STOP_AFTER:g}}}',
            f'  - {{kind: location, identity: 3, path: B, at: {l3:g}}}',
            f'  - {{kind: stop, station: W3, path: B, at: {l3 + STOP_AFTER:g}}}',
            'start: {path: A, at: 1.0}',
            '# The route map: the route leaves wire A at L1 and wire B at L3, 15 degrees left.',
            "srm_map: ['1:15', '3:15']"]


def fleet_floor_text(name: str = 'fleet_1983', extension: float = EXTENSION,
                     trucks: int = FLEET_TRUCKS) -> str:
    """Return the layout file of the lengthened room, parking `trucks` (see the module doc)."""
    a_houses = houses(13.0 + extension, A_FIRST)
    b_houses = houses(11.0 + extension, B_FIRST)
    lines = [
        f'# The fleet floor: demo_1983 lengthened by {extension:g} m, house-numbered locations',
        '# (Baker 1983, 8.5). Written by agv_nodes.world.fleet_floor; see its docstring.',
        f'layout: {name}',
        'description: The demonstration room of Baker 1983 (7.2, fig 7.14) lengthened for a '
        'fleet, its locations house-numbered along the wires (8.5)',
        'vehicle: electruk',
        'kind: wire',
        'sensor: {standoff: 0.300, lateral: 0.45}',
        *room_wires(extension, ARC, 4.0),
        'stations:',
        '  - {id: W1, has_load: false, capacity: 1}',
        '  - {id: W3, has_load: false, capacity: 1}']
    names = [(f'A{k + 1}', 'A', at) for k, at in enumerate(a_houses)] + \
        [(f'B{k + 1}', 'B', at) for k, at in enumerate(b_houses)]
    lines += house_stations(names)
    lines.append('markers:')
    for k, (house, wire, at) in enumerate(names):
        index = k if wire == 'A' else k - len(a_houses)
        lines += house_markers(house, wire, at, 0 if index % 2 == 0 else 2)
    lines += [*route_map_markers(extension, ARC),
              '# A truck per place (agv-launch --trucks N): every other house, a block between.']
    parking = [f'{house}.1' for house, _, _ in names][::2][:trucks]
    if len(parking) < trucks:
        raise ValueError(f'{trucks} trucks: the floor lengthened by {extension:g} m parks '
                         f'{len(parking)}')
    lines.append(f'parking: [{", ".join(parking)}]')
    return '\n'.join(lines) + '\n'


def extension_for(trucks: int) -> float:
    """Return the lengthening that parks `trucks` trucks (at least the fleet floor's)."""
    extension = EXTENSION
    while len(houses(13.0 + extension, A_FIRST) + houses(11.0 + extension, B_FIRST)) \
            < 2 * trucks:
        extension += PITCH
    return extension


DEMO_LOADS = {'A': ('W0', 'W2'), 'B': ('W1', 'W3')}  # demo_1983's two loads, first station first


def programme_loads(stations: Iterable[str], trucks: int) -> dict[str, tuple[str, str]]:
    """Return the loads a fleet programme sends round, each between two stations.

    On a house-numbered floor one per truck, load k between Ak and Bk (it starts at Ak, which
    has a load); elsewhere demo_1983's two, A between W0 and W2 and B between W1 and W3. The
    next transfer of a load is sent when its last one is done, so every transfer is possible
    whatever order the trucks finish in.
    """
    have = set(stations)
    pairs = [(f'A{k}', f'B{k}') for k in range(1, trucks + 1)]
    if all(a in have and b in have for a, b in pairs):
        return {f'load{a[1:]}': (a, b) for a, b in pairs}
    missing = sorted({s for pair in DEMO_LOADS.values() for s in pair} - have)
    if missing:
        raise ValueError(f'no stations for a programme of {trucks} trucks: neither A1..A{trucks} '
                         f'with B1..B{trucks} nor {", ".join(missing)}')
    return dict(DEMO_LOADS)
