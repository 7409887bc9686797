"""A fleet's floor with two loops: the house-numbered room widened, with a crossover between legs.

fleet_1983 (agv_nodes.world.fleet_floor) is one one-way loop: a truck has one way to anywhere,
and a truck standing in that way can only be waited for. This floor adds a second, shorter
loop. The room is widened so that a third wire, C, fits between the two legs: C runs east
beside A's south leg, turns about (a half circle of `CROSS_RADIUS`) and runs west beside B's
north leg. A truck leaves A for C at the junction marker JA by a software-resident manoeuvre
its task chooses (`srm at N angle 15`, Baker 1983, 7.2 task 7), and leaves C for B at C's exit
marker CX the same way (15 degrees right). A truck that is not told to stays on A: the route
map (SRMs at L1 and L3, as in demo_1983) is the big loop, the crossover the small one.

JA stands where the `JUNCTION`-th house would, with no workstation: a truck working there
would close both ways at once. C has one workstation (C1, a stop marker after C's first
location marker): a place to wait off both legs. The houses a crossover's manoeuvre sweeps
over are left out (a truck standing there would be in the way of one leaving or joining a
leg), and identities alternate along every way a truck can drive, so no two markers of one
identity follow each other (the truck reports only the last location it read, Baker 1983,
fig 6.2).

`config/layouts/loops_1983.yaml` is this module's floor; a test holds the file equal to it.
"""

from __future__ import annotations

import math

from agv_nodes.world.fleet_floor import (
    A_FIRST,
    B_FIRST,
    EXTENSION,
    STOP_AFTER,
    house_markers,
    house_stations,
    houses,
    room_wires,
    route_map_markers,
)

GAP = 1.5  # m from a leg to C beside it: two trucks side by side clear by 0.6 m
CROSS_RADIUS = 2.0  # m, C's half circle: the Electruk turns no tighter than ~1.4 m
ARC = GAP + CROSS_RADIUS + 0.5  # m, the room's end radius: B lies 1 m inside A's return
WIDTH = 2 * (GAP + CROSS_RADIUS)  # m from A's south leg to B's north leg
JUNCTION = 4  # where C leaves A: the place of A's 4th house (1-based), JA instead
SRM_ANGLE = 15  # degrees of both crossover manoeuvres (as the route map's)
C_START = 1.0  # m east of the junction where C begins
C_HOUSE = 7.5  # m along C to its location marker C1 (the manoeuvre lands before it)
C_EAST = 10.0  # m of C's eastward leg
EXIT_AFTER = 2.0  # m along C's westward leg to its exit marker
C_SPUR = 4.0  # m of C beyond its exit marker
SWEEP = GAP / math.tan(math.radians(SRM_ANGLE)) + 2.0  # m of a leg a manoeuvre passes over


def _kept(places: list[float], start: float, end: float) -> list[float]:
    """Return the house places whose location, stop and a truck's length avoid [start, end]."""
    return [at for at in places if at + STOP_AFTER + 1.0 < start or at - 1.0 > end]


def loops_floor_text(name: str = 'loops_1983', extension: float = EXTENSION) -> str:
    """Return the layout file of the two-loop floor (see the module docstring)."""
    a_all = houses(13.0 + extension, A_FIRST)
    junction = a_all[JUNCTION - 1]
    a_places = _kept(a_all, junction - 0.01, junction + SWEEP)
    c_x0 = -3.0 + junction + C_START  # A starts at x = -3
    c_exit_x = c_x0 + C_EAST - EXIT_AFTER  # the exit marker's x, on the westward leg
    b_exit = 7.0 + extension - c_exit_x  # along B, which runs west from x = 7 + extension
    b_places = _kept(houses(11.0 + extension, B_FIRST), b_exit - 1.0, b_exit + SWEEP)
    c_exit = round(C_EAST + math.pi * CROSS_RADIUS + EXIT_AFTER, 3)
    lines = [
        f'# The two-loop fleet floor: fleet_1983 widened to {WIDTH:g} m with a crossover wire C',
        '# (Baker 1983, 7.2, 8.5). Written by agv_nodes.world.loops_floor; see its docstring.',
        f'layout: {name}',
        'description: The house-numbered fleet floor of Baker 1983 (7.2, 8.5) widened, with a '
        'crossover that makes a second, shorter loop',
        'vehicle: electruk',
        'kind: wire',
        'sensor: {standoff: 0.300, lateral: 0.45}',
        *room_wires(extension, ARC, WIDTH),
        '  - id: C',
        f'    start: [{c_x0:g}, {GAP:g}, 0.0]',
        '    segments:',
        f'      - straight: {C_EAST:g}',
        f'      - {{arc: {CROSS_RADIUS:g}, angle: 180}}',
        f'      - straight: {EXIT_AFTER + C_SPUR:g}',
        'stations:',
        '  - {id: W1, has_load: false, capacity: 1}',
        '  - {id: W3, has_load: false, capacity: 1}',
        '  - {id: C1, has_load: false, capacity: 1}']
    names = [(f'A{k + 1}', 'A', at) for k, at in enumerate(a_places)] + \
        [(f'B{k + 1}', 'B', at) for k, at in enumerate(b_places)]
    lines += house_stations(names)
    lines.append('markers:')
    # Identities alternate along A (the junction among its houses), along B, and along the
    # small loop: JA, C1, CX, then B's first house (identity 0).
    a_order = sorted([*a_places, junction])
    j_identity = 0 if a_order.index(junction) % 2 == 0 else 2
    if j_identity != 2:
        raise ValueError(f"junction house {JUNCTION}: CX would share B1's identity 0")
    for k, (house, wire, at) in enumerate(names):
        index = a_order.index(at) if wire == 'A' else k - len(a_places)
        if wire == 'A' and index == a_order.index(junction) + 1:
            lines.append(f'  - {{kind: location, identity: {j_identity}, name: JA, path: A, '
                         f'at: {junction:g}}}')
        lines += house_markers(house, wire, at, 0 if index % 2 == 0 else 2)
    lines += [f'  - {{kind: location, identity: {2 - j_identity}, name: C1, path: C, '
              f'at: {C_HOUSE:g}}}',
              f'  - {{kind: stop, station: C1, path: C, at: {C_HOUSE + STOP_AFTER:g}}}',
              f'  - {{kind: location, identity: {j_identity}, name: CX, path: C, '
              f'at: {c_exit:g}}}',
              *route_map_markers(extension, ARC),
              '# Where a task may leave a wire by an SRM (srm at N angle A): onto C and off it.',
              f"junctions: ['JA:{SRM_ANGLE}', 'CX:{-SRM_ANGLE}']",
              '# A truck per place (agv-launch --trucks N): every other house, a block between.']
    parking = [f'{house}.1' for house, _, _ in names][::2]
    lines.append(f'parking: [{", ".join(parking)}]')
    return '\n'.join(lines) + '\n'
