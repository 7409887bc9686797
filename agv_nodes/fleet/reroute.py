"""The watchdog's last resort: a truck that waits on trucks that cannot move takes another way.

A part the Dispatcher (agv_nodes.fleet.dispatcher) owns, kept apart because it acts only when
the grant policy has not been enough; it is given the dispatcher's reservations and its way
planner and stall test, and is asked once a step with the trucks and the step's deadlocks.

A truck standing at its decision point whose next corridor is held by trucks that cannot move
waits for nothing. Those are: a truck broken (its task failed where it stands), one off the
broker (it is sent nothing), one of a deadlock (a cycle of the wait-for graph, each truck of it
waiting for the next), and one that waits only on such trucks. After `reroute_after` s of that,
the dispatcher plans the rest of the truck's job anew, its pick and drop where they were, on a
way that enters none of the blocks it waits for. Where the floor has one (a second loop, a
junction: agv_nodes.world.loops_floor), the way is released by an order update stitched at the
decision point (VDA 5050 6.6.2), as any grant is. In a deadlock one truck of the cycle is
re-routed at a time, the first by name: its leaving may be what frees the others.

The standard's other way, cancelOrder and a new order, is not taken: the truck stands at its
decision point with the base done, so an update changes only the horizon, and the transport's
pick or drop stays in the order the master tracks.

Where no such way exists (a one-way loop, or the pick or drop inside a block it waits for),
the truck waits on, and a deadlock stays in the dispatcher's `deadlocks` for whoever watches.
`reroutes` keeps (truck, order id, blocks avoided, seconds it had waited) of each re-routing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

from agv_nodes.fleet.blocks import Reservations
from agv_nodes.fleet.jobs import Job, Truck
from agv_nodes.fleet.settings import DispatcherSettings
from agv_nodes.vda5050.common import Action

# s a truck waits on trucks that cannot move before it is re-routed (parameter reroute_after)
REROUTE_AFTER: float = DispatcherSettings().reroute_after
# (start, passed, [(stop node, its action)], nodes to avoid) -> (path, {path index: action})
Planner = Callable[[str, bool, list[tuple[str, Action | None]], frozenset[str]],
                   tuple[list[str], dict[int, Action]] | None]


class Rerouting:
    """Re-routing of trucks stuck behind trucks that cannot move (see the module docstring)."""

    def __init__(self, reservations: Reservations, plan: Planner,
                 stalled: Callable[[Truck], bool], reroute_after: float = REROUTE_AFTER) -> None:
        self.reservations = reservations
        self._plan = plan
        self._stalled = stalled
        self.reroute_after = reroute_after  # s
        # (truck, order, blocks avoided, s waited) of each re-routing
        self.reroutes: list[tuple[str, str, list[str], float]] = []

    def reroute(self, fleet: Iterable[Truck], trucks: list[Truck],
                deadlocks: list[list[str]], now: float) -> None:
        """Re-route the first truck, by name, that has waited long enough on immovable ones.

        `fleet`: every truck; `trucks`: those heard from this step; `deadlocks`: its cycles.
        """
        cannot_move = {t.name for t in fleet if t.broken or t.offline}
        cannot_move.update(name for cycle in deadlocks for name in cycle)
        grown = True
        while grown:  # and those that wait only on such trucks, themselves stuck behind them
            stuck = {t.name for t in trucks if t.name not in cannot_move
                     and self._waits_on_immovable(t, cannot_move)}
            cannot_move |= stuck
            grown = bool(stuck)
        for t in sorted(trucks, key=lambda t: t.name):
            waited = self._waits_on_immovable(t, cannot_move)
            if not waited:
                t.blocked_since = None
                continue
            if t.blocked_since is None:
                t.blocked_since = now
            if now - t.blocked_since < self.reroute_after:
                continue
            job = t.job
            assert job is not None
            avoid = frozenset(n for b in waited for n in self.reservations.blocks[b].nodes)
            if self._replan(job, avoid):
                self.reservations.stop_waiting(t.name)
                self.reroutes.append((t.name, job.order_id, sorted(waited),
                                      now - t.blocked_since))
                t.blocked_since = None
                return

    def _waits_on_immovable(self, t: Truck, cannot_move: set[str]) -> set[str]:
        """Return the blocks a stalled truck waits for when only immovable trucks hold them."""
        job = t.job
        if job is None or job.over or t.broken or t.offline or not self._stalled(t):
            return set()
        waited = self.reservations.waiting(t.name)
        holders = {self.reservations.holder(b) for b in waited} - {None, t.name}
        return waited if holders and holders <= cannot_move else set()

    def _replan(self, job: Job, avoid: frozenset[str]) -> bool:
        """Plan the job on from its decision point around `avoid`; False when no way does."""
        e, path = job.base_end, job.path
        passed = job.passed or e > 0
        rest = [(path[i], job.actions.get(i))
                for i in sorted({i for i in job.actions if i > e} | {len(path) - 1})]
        plan = self._plan(path[e], passed, rest, avoid)
        if plan is None or plan[0] == path[e:]:
            return False
        new_path, actions = plan
        job.path = path[:e] + new_path
        job.actions = {i: a for i, a in job.actions.items() if i <= e}
        job.actions.update({e + i: a for i, a in actions.items()})
        return True
