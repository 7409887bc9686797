"""The way the 1983 truck's tasks drive: to the next marker of a location, by the route map.

A task (docs/tasks.md) names a location identity and a stop marker; the truck drives along the
route map to the NEXT location marker of that identity and on to the stop marker. So where a
floor repeats identities (house numbers, Baker 1983, 8.5: agv_nodes.world.fleet_floor), one
task cannot reach a stop marker past another marker of its identity. The truck gets there by
several: `pass N` for each marker of that identity it must drive past (a modern task: on
past the next marker of N without stopping), then the stop task. `task_legs` finds those
markers; a master need not know: the bridge sends the passes.
"""

from __future__ import annotations

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
        on = graph.route(marker, stop)
        return None if on is None else (on, 0)
    to_marker, on = graph.route(anchor, marker), graph.route(marker, stop)
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


def task_way(graph: TrackGraph, anchor: str, anchor_passed: bool, stop: str) -> list[str] | None:
    """Return the nodes the truck drives through from `anchor` to `stop` by its tasks (None: none).

    One task's way (one_task_way), or on a floor of repeated identities that way with passes
    (task_legs).
    """
    legs = task_legs(graph, anchor, anchor_passed, stop)
    return None if legs is None else legs[0]
