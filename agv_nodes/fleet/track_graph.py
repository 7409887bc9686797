"""The track graph of a wire layout: markers as nodes, the wire between them as edges.

A master control (VDA 5050) and the dispatcher plan on it. Nodes are the layout's location
markers (`L0`..`L3`) and stop markers (`W1.1`: station W1's first), named as the truck reports
them; an edge is the way from one to the next in the direction of travel (one-way wires, Baker
1983, 7.2). Edges along one wire take their length from the markers' places on it (the
wire's length between them). Where the
route map leaves a wire at a location by an SRM (7.2, task 7), where the SRM lands is not a
property of the wire but of the truck: the graph takes it from the layout check's drive of the
route map (agv_nodes.world.layout_check.route_passes), so an SRM edge runs from the location
marker to the first card the truck passes after landing, as long as it drove. A station after
such a location is a branch: the truck that stops there leaves it by the same SRM (the
executive starts it on departure), so its edge to the landing is estimated as the location's
SRM edge less the wire between them (not driven: the SRM from the station lands a little
differently; on demo_1983 the estimate is within a few cm).

A junction (the layout's `junctions`) is a location marker where a task may leave the wire by
an SRM (`srm at N angle A`) and a truck not told to stays on it: both ways are edges, the SRM's
marked `chosen`. The graph learns a junction's edge and the way it opens the same way, from a
drive that takes that junction's SRM (layout_check.junction_passes). The route map's own way
(`route(..., junctions=False)`) leaves chosen edges out: it is where a truck goes untold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import heapq
from itertools import pairwise
import math

from agv_nodes.world.layout import Layout, LayoutError, Marker
from agv_nodes.world.layout_check import junction_passes, route_passes
from agv_nodes.world.settings import WorldParams


@dataclass(frozen=True)
class TrackNode:
    """A marker the truck can report: a location it passes or a stop marker it can stop at."""

    id: str  # Marker.name: 'L2', 'W2.1'
    kind: str  # 'location' | 'stop'
    location: int  # the location marker identity (a stop marker's: the one before it)
    conveyor: int  # stop marker: 0 first, 1 second; location: -1
    station: str  # stop marker's station ('' for a location)
    x: float  # the wire's point abreast of the card, m (world frame): where the sensor reads it
    y: float
    theta: float  # the wire's heading there, rad in (-pi, pi]
    # The location marker it belongs to (its own id for a location): with identities repeated
    # on a floor (house numbers, Baker 1983, 8.5), `location` alone does not say which.
    location_marker: str = ''

    @property
    def stoppable(self) -> bool:
        """Return True where a task can leave the truck standing (a stop marker)."""
        return self.kind == 'stop'


@dataclass(frozen=True)
class TrackEdge:
    """The way from one node to the next, in the direction of travel."""

    id: str  # '<start>-<end>'
    start: str
    end: str
    length: float  # m
    srm_angle: int = 0  # degrees of the SRM the edge takes off its wire (0: along the wire)
    chosen: bool = False  # a junction's SRM: taken only when a task says so (srm at N)


class TrackGraph:
    """Nodes and one-way edges, with shortest routes between nodes."""

    def __init__(self, nodes: list[TrackNode], edges: list[TrackEdge], start: str = '') -> None:
        self.start = start  # the first node a truck meets from the layout's start ('' unknown)
        self.nodes = {n.id: n for n in nodes}
        self.edges = {e.id: e for e in edges}
        self._out: dict[str, list[TrackEdge]] = {n: [] for n in self.nodes}
        for e in edges:
            if e.start not in self.nodes or e.end not in self.nodes:
                raise ValueError(f'edge {e.id}: {e.start} or {e.end} is not a node')
            self._out[e.start].append(e)
        # True when a task can choose a way here (a junction's SRM edge)
        self.has_junctions = any(e.chosen for e in edges)

    def edge(self, start: str, end: str) -> TrackEdge | None:
        """Return the edge from `start` to `end`, or None when there is none."""
        return next((e for e in self._out.get(start, ()) if e.end == end), None)

    def direction(self, edge: TrackEdge) -> str | None:
        """Return the way an edge out of a junction takes (VDA 5050 edge.direction), or None.

        'left' or 'right' for the junction's SRM (by the sign of its angle), 'straight' for the
        edge along the wire; None for an edge that leaves no junction.
        """
        if edge.chosen:
            return 'left' if edge.srm_angle > 0 else 'right'
        if any(e.chosen for e in self._out.get(edge.start, ())):
            return 'straight'
        return None

    def successors(self, node: str) -> list[TrackEdge]:
        """Return the edges leaving `node`."""
        return list(self._out.get(node, ()))

    def route(self, start: str, end: str, *, via_stops: bool = False, junctions: bool = True,
              avoid: frozenset[str] = frozenset()) -> list[str] | None:
        """Return the shortest node sequence from `start` to `end` (None: unreachable).

        A route from a node to itself is one lap when the graph has one (a loop), as a truck at
        a station sent back to it drives round. Branches to stop markers are left out of the
        way unless they are `end`, or `via_stops` (their stop markers are passed, not stopped
        at, by a truck going on; a branch after an SRM location is a longer way). Without
        `junctions`, the route map's way: no junction's SRM. No node of `avoid` is entered.
        """
        if start not in self.nodes or end not in self.nodes:
            return None
        best: dict[str, float] = {}
        queue: list[tuple[float, list[str]]] = [(0.0, [start])]
        while queue:
            dist, path = heapq.heappop(queue)
            here = path[-1]
            if here == end and len(path) > 1:
                return path
            if best.get(here, float('inf')) <= dist and len(path) > 1:
                continue
            if len(path) > 1:
                best[here] = dist
            for e in self._out[here]:
                if e.end != end and not via_stops and self._is_branch(e):
                    continue
                if (e.chosen and not junctions) or e.end in avoid:
                    continue
                heapq.heappush(queue, (dist + e.length, [*path, e.end]))
        return None

    def _is_branch(self, e: TrackEdge) -> bool:
        """Return True for the edge into a station that an SRM location's route map skips."""
        return not e.srm_angle and any(o.srm_angle and not o.chosen for o in self._out[e.start]
                                       if o is not e)

    def length(self, nodes: list[str]) -> float:
        """Return the length in m of the way through `nodes` (each pair must be an edge)."""
        total = 0.0
        for a, b in pairwise(nodes):
            e = self.edge(a, b)
            if e is None:
                raise ValueError(f'no edge from {a} to {b}')
            total += e.length
        return total


def _location_of(marker: Marker, markers: list[Marker]) -> Marker:
    """Return the location marker a stop marker belongs to: the last one before it."""
    before = [m for m in markers if m.kind == 'location' and m.path == marker.path
              and m.at < marker.at]
    if not before:
        raise LayoutError(f'stop marker {marker.name} on {marker.path} at {marker.at} m has no '
                          'location marker before it on its wire')
    return max(before, key=lambda m: m.at)


def _check_repeats(layout: Layout, passed: list[Marker]) -> None:
    """Refuse a route that meets one identity at two location markers in a row.

    The truck reports the last location it recognised (Baker 1983, fig 6.2); the second of two
    in a row would change nothing it reports, so no one could tell that it had passed it.
    """
    locations = [m for m in passed if m.kind == 'location']
    for a, b in pairwise(locations):
        if a.identity == b.identity and a is not b:
            raise LayoutError(f'{layout.file}: key markers: location markers {a.name} and '
                              f'{b.name} (both identity {a.identity}) follow each other on the '
                              'route: the truck could not report passing the second')


def _add_junctions(layout: Layout, world: WorldParams | None, by_name: dict[str, Marker],
                   srm: dict[int, int], add: Callable[..., None]) -> None:
    """Add each junction's SRM edge and the edges of the way it opens (module docstring)."""
    chosen = {name: int(angle) for name, _, angle in
              (e.partition(':') for e in layout.junctions)}
    for junction, passes in junction_passes(layout, world).items():
        at = next((i for i, (name, _) in enumerate(passes) if name == junction), None)
        if at is None or at + 1 >= len(passes):
            raise LayoutError(f'{layout.file}: key junctions: {junction}: a truck leaving the '
                              'wire there by its SRM passes no card after it')
        _add_driven(add, passes[at:], by_name, srm, {junction: chosen[junction]})


def _add_driven(add: Callable[..., None], passes: list[tuple[str, float]],
                by_name: dict[str, Marker], srm: dict[int, int],
                junctions: dict[str, int] | None = None) -> None:
    """Add the edge between each two cards a drive passed one after the other.

    Along a wire the wire's own length: the drive's sensor point weaves about it. Off a wire by
    an SRM, the route map's or a junction's the drive took (`junctions`, chosen edges), the
    length driven.
    """
    for (a, da), (b, db) in pairwise(passes):
        ma, mb = by_name[a], by_name[b]
        if junctions and a in junctions:
            add(a, b, db - da, junctions[a], chosen=True)
            continue
        angle = srm.get(ma.identity, 0) if ma.kind == 'location' else 0
        along = not angle and ma.path == mb.path and mb.at > ma.at
        add(a, b, mb.at - ma.at if along else db - da, angle)


def track_graph(layout: Layout, world: WorldParams | None = None) -> TrackGraph:
    """Return the track graph of a wire layout (see the module docstring).

    Raises LayoutError for a layout that has none: a camera or rig floor, or no route map
    round its markers.
    """
    if layout.kind != 'wire' or layout.vehicle != 'electruk':
        raise LayoutError(f'{layout.file}: a {layout.kind} layout for the {layout.vehicle} has '
                          'no track graph (wire layouts of the Electruk only)')
    markers = [m for m in layout.markers if m.kind in ('location', 'stop')]
    nodes = []
    for m in markers:
        x, y, heading = (float(v) for v in layout.paths[m.path].pose_at(m.at))
        location = m if m.kind == 'location' else _location_of(m, markers)
        nodes.append(TrackNode(m.name, m.kind, location.identity,
                               m.identity if m.kind == 'stop' else -1,
                               m.station, round(x, 4), round(y, 4),
                               round(math.atan2(math.sin(heading), math.cos(heading)), 6)
                               + 0.0,  # + 0.0: no -0.0
                               location.name))
    srm = {int(loc): int(angle) for loc, angle in (e.split(':') for e in layout.srm_map)}
    edges: dict[tuple[str, str], TrackEdge] = {}

    def add(a: str, b: str, length: float, angle: int = 0, chosen: bool = False) -> None:
        edges.setdefault((a, b), TrackEdge(f'{a}-{b}', a, b, round(length, 3), angle, chosen))

    by_name = {m.name: m for m in markers}
    passes = route_passes(layout, world)
    _check_repeats(layout, [by_name[name] for name, _ in passes if name in by_name])
    _add_driven(add, passes, by_name, srm)
    # Along each wire: the stop markers the route map's SRMs skip, and the SRM off their station.
    for loc_id, angle in srm.items():
        loc = next((m for m in markers if m.kind == 'location' and m.identity == loc_id), None)
        if loc is None:
            continue
        landing = next((e for e in edges.values() if e.start == loc.name and e.srm_angle), None)
        after = sorted((m for m in markers if m.path == loc.path and m.at > loc.at
                        and m.kind == 'stop' and _location_of(m, markers) is loc),
                       key=lambda m: m.at)
        previous = loc
        for m in after:
            add(previous.name, m.name, m.at - previous.at)
            if landing is not None:
                add(m.name, landing.end, landing.length - (m.at - loc.at), angle)
            previous = m
    _add_junctions(layout, world, by_name, srm, add)
    if not edges:
        raise LayoutError(f'{layout.file}: the route map passes no two markers: no track graph')
    return TrackGraph(nodes, list(edges.values()), passes[0][0])
