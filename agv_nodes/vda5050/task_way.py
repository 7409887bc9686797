"""The way the 1983 truck's tasks drive: to the next marker of a location, by the route map.

A task (docs/tasks.md) names a location identity and a stop marker; the truck drives along the
route map to the NEXT location marker of that identity and on to the stop marker. So where a
floor repeats identities (house numbers, Baker 1983, 8.5: agv_nodes.world.fleet_floor), one
task cannot reach a stop marker past another marker of its identity. The truck gets there by
several: `pass N` for each marker of that identity it must drive past (a modern task: on
past the next marker of N without stopping), then the stop task. `task_legs` finds those
markers; a master need not know: the bridge sends the passes.

Where the floor has junctions (agv_nodes.fleet.track_graph), a way may take a junction's SRM:
the truck gets there by `srm at N angle A` (again after a `pass N` for each marker of N before
the junction), lands on the other wire and goes on from the first card it meets there.
`way_tasks` finds those tasks for a way; `task_way` plans the shortest way the tasks can drive.
"""

from __future__ import annotations

from itertools import pairwise

from agv_nodes.fleet.track_graph import TrackGraph


def _marker_of(graph: TrackGraph, stop: str) -> str | None:
    target = graph.nodes[stop]
    return target.location_marker or next(
        (n.id for n in graph.nodes.values()
         if n.kind == 'location' and n.location == target.location), None)


def _drive(graph: TrackGraph, anchor: str, anchor_passed: bool, stop: str
           ) -> tuple[list[str], int] | None:
    """Return the route-map way to `stop` past its own location marker, and that marker's index."""
    marker = _marker_of(graph, stop)
    if marker is None:
        return None
    if anchor == marker and not anchor_passed:
        on = graph.route(marker, stop, junctions=False)
        return None if on is None else (on, 0)
    to_marker = graph.route(anchor, marker, junctions=False)
    on = graph.route(marker, stop, junctions=False)
    if to_marker is None or on is None:
        return None
    return to_marker + on[1:], len(to_marker) - 1


def _repeat(graph: TrackGraph, way: list[str], marker_at: int, anchor_passed: bool) -> int:
    """Return the index of the first marker of the stop's identity before its own (-1: none)."""
    identity = graph.nodes[way[marker_at]].location
    for k in range(0 if not anchor_passed else 1, marker_at):
        node = graph.nodes[way[k]]
        if node.kind == 'location' and node.location == identity:
            return k
    return -1


def one_task_way(graph: TrackGraph, anchor: str, anchor_passed: bool, stop: str
                 ) -> list[str] | None:
    """Return the nodes ONE task drives through from `anchor` to stop marker `stop` (None: none).

    The way is the route to the stop's location marker (a lap when the truck is on it already,
    `anchor_passed`) and on; the route map's way is the graph's route that leaves out branches
    to stations (TrackGraph.route). A way that meets another marker of the stop's identity
    first is not one task's: the task would stop there.
    """
    drive = _drive(graph, anchor, anchor_passed, stop)
    if drive is None or _repeat(graph, *drive, anchor_passed) >= 0:
        return None
    return drive[0]


def task_legs(graph: TrackGraph, anchor: str, anchor_passed: bool, stop: str
              ) -> tuple[list[str], list[int]] | None:
    """Return the way to `stop` by tasks and the way's indices of the markers passed by task.

    Those are the location markers of the stop's identity the way meets before the stop's own:
    each is passed by a task `pass N` (the next marker of N, driven past without stopping),
    and the last task, to the stop, then meets its own marker first.
    """
    drive = _drive(graph, anchor, anchor_passed, stop)
    if drive is None:
        return None
    way, marker_at = drive
    identity = graph.nodes[way[marker_at]].location
    passes = [k for k in range(1 if anchor_passed else 0, marker_at)
              if graph.nodes[way[k]].kind == 'location'
              and graph.nodes[way[k]].location == identity]
    start = passes[-1] if passes else 0
    if one_task_way(graph, way[start], anchor_passed or bool(passes), stop) != way[start:]:
        return None
    return way, passes


def way_tasks(graph: TrackGraph, way: list[str], anchor_passed: bool
              ) -> list[tuple[int, str]] | None:
    """Return the tasks before the last that drive `way`, each with the index it ends at.

    `way` runs from where the truck is (way[0], passed or not) to a stop marker; the tasks are
    `pass N` and, at each junction whose SRM the way takes, `srm at N angle A`; the stop's own
    task (which carries its action) is the caller's. None: no tasks drive that way (a part of
    it is not the route map's way between two junctions).
    """
    tasks: list[tuple[int, str]] = []
    start, passed = 0, anchor_passed
    for k, (a, b) in enumerate(pairwise(way)):
        edge = graph.edge(a, b)
        if edge is None:
            return None
        if not edge.chosen:
            continue
        junction = graph.nodes[a]
        first = graph.nodes[way[start]]
        to_junction = [a] if start == k and not passed else graph.route(way[start], a,
                                                                         junctions=False)
        if to_junction != way[start:k + 1]:
            return None
        passes = [(i, f'pass {junction.location}') for i in range(start + int(passed), k)
                  if graph.nodes[way[i]].kind == 'location'
                  and graph.nodes[way[i]].location == junction.location]
        if not tasks and not passes and first.stoppable \
                and first.location == junction.location:
            # From a stop of the junction's location `srm at N` leaves at once (as from a
            # station after the route map's SRM): a pass of the next marker comes first.
            on = next((i for i in range(start + 1, k) if graph.nodes[way[i]].kind == 'location'),
                      None)
            if on is None:
                return None
            passes = [(on, f'pass {graph.nodes[way[on]].location}')]
        tasks += passes
        tasks.append((k, f'srm at {junction.location} angle {edge.srm_angle}'))
        start, passed = k + 1, False  # on the new wire, before the first card it meets
    legs = task_legs(graph, way[start], passed, way[-1])
    if legs is None or legs[0] != way[start:]:
        return None
    return tasks + [(start + i, f'pass {graph.nodes[way[start + i]].location}')
                    for i in legs[1]]


def task_way(graph: TrackGraph, anchor: str, anchor_passed: bool, stop: str,
             avoid: frozenset[str] = frozenset()) -> list[str] | None:
    """Return the nodes the truck drives through from `anchor` to `stop` by its tasks (None: none).

    On a floor with junctions the shortest way its tasks can drive (way_tasks), else (or when
    there is none) the route map's: one task's way (one_task_way), or on a floor of repeated
    identities that way with passes (task_legs). No node of `avoid` is on the way.
    """
    if graph.has_junctions:
        way = graph.route(anchor, stop, avoid=avoid)
        if way is not None and way_tasks(graph, way, anchor_passed) is not None:
            return way
    legs = task_legs(graph, anchor, anchor_passed, stop)
    return None if legs is None or avoid & set(legs[0]) else legs[0]
