"""The central computer: transport orders in, VDA 5050 orders for each truck out.

No ROS, no MQTT and no clock: the caller feeds each truck's State (`on_state`) and sends what
`step` returns. A transport order (load at station S, take it to station D) goes to the
nearest idle truck; its order is the task language's way (order_tasks.task_way) from the
truck's lastNodeId to the pick (action `pick`) and on to the drop (action `drop`), the first
stop marker of each station. Traffic control is by blocks (agv_nodes.fleet.blocks): the base
is released only through blocks granted to the truck and ends at a stop marker; the rest is
horizon, released by order updates stitched on at the decision point as more is granted.

The grant policy, and why it cannot deadlock on a one-way loop:
- a truck holds the blocks its body may be in (its footprint) and those of its base; the rest
  is released as State.lastNodeId moves on;
- it is granted whole corridors: every block up to the next stop marker where its base may
  end, or none; as many corridors ahead as are free;
- a block it holds already is granted again only where its way never left it (a lap waits
  until the truck has left the block once);
- a truck standing at its decision point whose corridor is refused, but whose next block is
  free, is re-routed by an update to a stop marker of that block: a passing place (W1.1 or
  W3.1 for a truck that would otherwise run L1 -> L3 -> L0 in one go);
- an idle truck holding a block another waits for is sent on to the nearest stop marker it
  can be granted (its parking spot when it has one).
So a truck that cannot move stands at a stop marker and holds the block it is in (on demo_1983
no stop marker is within a truck's length of the block before it). Every block of the loop has
a stop marker, and every way out of a block leads into the next block of the ring. A waiting
truck waits for the holder of its next block; that one waits for the holder of its own next
block, or makes way when idle; with fewer trucks than blocks the chain ends at a truck whose
next block is free, and it moves: the fleet never comes to a standstill. The wait-for graph's
cycles of standing trucks are kept in `deadlocks` as a watchdog for layouts or fleets where
this does not hold (as many trucks as blocks). Its last resort is agv_nodes.fleet.reroute: a
truck at its decision point that waits only on trucks that cannot move (deadlocked, broken,
off the broker) is re-routed by an update where the floor has another way (a second loop);
on a one-way loop there is none, and the deadlock stands, reported.

A truck whose task failed (error `taskFailed`, or FAILED actions of its order) fails its
transport (`failed`) and keeps the blocks where it may stand; it gets no work until its state
shows no errors. One off the broker (`set_online`) keeps its blocks and is sent nothing.
"""

from __future__ import annotations

from collections import deque
from itertools import count

from pydantic import BaseModel

from agv_nodes.fleet.blocks import TRUCK_LENGTH, Block, Reservations
from agv_nodes.fleet.jobs import (
    INSTANT_ACTIONS,
    ORDER,
    Job,
    TransportOrder,
    Truck,
    failure_words,
    hard_action,
    header,
    order_message,
    task_failed,
)
from agv_nodes.fleet.reroute import REROUTE_AFTER, Rerouting
from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.vda5050.common import Action, ActionParameter, BlockingType
from agv_nodes.vda5050.order import InstantActions
from agv_nodes.vda5050.state import ActionStatus, State
from agv_nodes.vda5050.task_way import task_way

__all__ = ['Dispatcher', 'TransportOrder']

TRAIL = 12  # nodes of a truck's way kept behind it: enough for its footprint


class Dispatcher:
    """Assign transport orders to trucks and drive them by VDA 5050 (see the module docstring)."""

    def __init__(self, graph: TrackGraph, trucks: list[str], *, manufacturer: str = 'agv_nodes',
                 blocks: list[Block] | None = None, parking: dict[str, str] | None = None,
                 positions: dict[str, str] | None = None,
                 truck_length: float = TRUCK_LENGTH,
                 reroute_after: float = REROUTE_AFTER) -> None:
        """Direct `trucks` on `graph`.

        `positions` is the stop marker each truck was set down at; the dispatcher tells each
        its own by initPosition (a truck knows where it is only from the markers it passes).
        """
        self.graph = graph
        self.manufacturer = manufacturer
        self.reservations = Reservations(graph, blocks)
        self.parking = dict(parking or {})
        self.truck_length = truck_length
        # the watchdog's last resort (fleet.reroute); `reroutes` its (truck, order, blocks
        # avoided, s waited) of each re-routing
        self.rerouting = Rerouting(self.reservations, self._plan, self._stalled, reroute_after)
        self.reroutes = self.rerouting.reroutes
        self.queue: deque[TransportOrder] = deque()
        self.assignments: dict[str, str] = {}  # transport id -> truck
        self.done: list[str] = []
        self.failed: list[str] = []
        self.failures: dict[str, str] = {}  # transport id -> why it failed, as the truck said
        self.deadlocks: list[list[str]] = []  # the wait cycles of the last step
        self.conflicts: list[tuple[str, str, str]] = []  # (block, truck, holder) found there
        self.trucks = list(trucks)  # their serial numbers
        self._trucks = {name: Truck(name) for name in trucks}
        self._positions = dict(positions or {})
        self._placing: set[str] = set()  # trucks sent their initPosition
        self._ways: dict[tuple[str, bool, str, frozenset[str]], list[str] | None] = {}
        self._serial = 0
        self._asked = count(1)  # stateRequest ids
        for name, node in self._positions.items():  # there before it is heard from: held
            self._trucks[name].trail = [node]
            self.reservations.occupy(name, self.reservations.block_of(node))

    # -- input -----------------------------------------------------------------------------
    def submit(self, transport: TransportOrder) -> None:
        """Queue a transport order; it goes to a truck in step(), first come first served."""
        for station in (transport.source, transport.destination):
            self._stop_of(station)  # raises for an unknown station
        self.queue.append(transport)

    def on_state(self, truck: str, state: State, now: float) -> None:
        """Take a truck's state: its progress, its finished or failed order, its errors."""
        t = self._trucks[truck]
        t.state = state
        node = state.last_node_id or self._positions.get(truck) or self.graph.start
        job = t.job
        if job is not None and job.sent and state.order_id == job.order_id:
            index = state.last_node_sequence_id // 2
            if t.pos < index < len(job.path) and job.path[index] == state.last_node_id:
                t.trail = (t.trail + job.path[t.pos + 1:index + 1])[-TRAIL:]
                t.pos = index
            statuses = {a.action_id: a.action_status for a in state.action_states}
            mine = [statuses.get(a.action_id) for a in job.actions.values()]
            if not job.over and (ActionStatus.FAILED in mine or task_failed(state)):
                job.over = job.failed = True
                if job.transport is not None:
                    self.failed.append(job.transport.id)
                    self.failures[job.transport.id] = failure_words(
                        state, {a.action_id for a in job.actions.values()})
            elif not job.over and state.order_update_id == job.update_id \
                    and t.pos == len(job.path) - 1 and not state.node_states \
                    and all(s == ActionStatus.FINISHED for s in mine):
                job.over = True
                if job.transport is not None:
                    self.done.append(job.transport.id)
        if t.trail[-1:] != [node]:  # first seen, or somewhere its order did not take it
            t.trail = [node]
        block = self.reservations.block_of(node)
        if self.reservations.holder(block) != truck:
            other = self.reservations.occupy(truck, block)  # it is there, granted or not
            if other is not None:
                self.conflicts.append((block, truck, other))
        if task_failed(state):
            t.broken = True
        elif not state.errors:
            t.broken = False

    # -- output ----------------------------------------------------------------------------
    def step(self, now: float) -> list[tuple[str, str, BaseModel]]:
        """Release, grant, assign and park; return (truck, topic, message) to send."""
        out: list[tuple[str, str, BaseModel]] = []
        trucks = [t for t in self._trucks.values() if t.state is not None]
        for t in trucks:
            if self._unplaced(t) and t.name not in self._placing and not t.offline:
                self._placing.add(t.name)
                out.append((t.name, INSTANT_ACTIONS, InstantActions(
                    **header(t, INSTANT_ACTIONS, self.manufacturer), actions=[Action(
                        action_type='initPosition', action_id=f'init-{t.name}',
                        blocking_type=BlockingType.HARD, action_parameters=[ActionParameter(
                            key='lastNodeId', value=self._positions[t.name])])])))
        for t in trucks:
            self.reservations.keep_only(t.name, self._needed(t))
        self._assign()
        for t in trucks:
            if t.job is not None and not t.job.over and not t.offline:
                self._extend(t, out)
        for t in trucks:
            if not self._idle(t) and (t.job is None or t.job.over):
                self.reservations.stop_waiting(t.name)
            if self._idle(t):
                self._park_or_yield(t, out)
        stuck = {t.name for t in trucks if self._stalled(t) or self._idle(t)}
        self.deadlocks = [c for c in self.reservations.deadlocks() if stuck.issuperset(c)]
        self.rerouting.reroute(self._trucks.values(), trucks, self.deadlocks, now)
        return out

    def state_requests(self) -> list[tuple[str, str, BaseModel]]:
        """Return a stateRequest to every truck: a master that (re)connects asks where they are.

        A state is sent on events and at least every 30 s; without asking, the master could
        wait that long to hear of a truck.
        """
        return [(t.name, INSTANT_ACTIONS, InstantActions(
            **header(t, INSTANT_ACTIONS, self.manufacturer), actions=[Action(
                action_type='stateRequest', action_id=f'state-{t.name}-{next(self._asked)}',
                blocking_type=BlockingType.NONE)])) for t in self._trucks.values()]

    def set_online(self, truck: str, online: bool) -> None:
        """Take a truck's connection (6.14); off the broker it is sent nothing (QoS 0: lost)."""
        self._trucks[truck].offline = not online

    def granted(self, truck: str) -> set[str]:
        """Return the blocks `truck` holds."""
        return self.reservations.held(truck)

    # -- blocks ------------------------------------------------------------------------------
    def _needed(self, t: Truck) -> set[str]:
        """Return the blocks a truck must keep: its footprint and the rest of its base."""
        keep = self.reservations.footprint(t.trail, self.truck_length)
        job = t.job
        if job is None or not job.sent:
            return keep
        end = job.base_end
        if job.failed and t.broken:  # stopped short of its next location marker, or there
            end = next((i for i in range(t.pos + 1, job.base_end + 1)
                        if self.graph.nodes[job.path[i]].kind == 'location'), job.base_end)
        elif job.over:
            end = t.pos
        return keep | set(self.reservations.blocks_of(job.path[t.pos:end + 1]))

    # -- planning ------------------------------------------------------------------------------
    def _way(self, start: str, passed: bool, stop: str, avoid: frozenset[str] = frozenset()
             ) -> list[str] | None:
        key = (start, passed, stop, avoid)
        if key not in self._ways:
            self._ways[key] = task_way(self.graph, start, passed, stop, avoid)
        return self._ways[key]

    def _stop_of(self, station: str) -> str:
        stops = sorted(n.id for n in self.graph.nodes.values()
                       if n.station == station and n.stoppable)
        if not stops:
            raise ValueError(f'no stop marker of station {station!r} in the track graph')
        return stops[0]

    def _plan(self, start: str, passed: bool, stops: list[tuple[str, Action | None]],
              avoid: frozenset[str] = frozenset()
              ) -> tuple[list[str], dict[int, Action]] | None:
        """Return the way through `stops` from `start` and its actions by path index."""
        path, actions = [start], {}
        for node, action in stops:
            way = self._way(path[-1], passed or len(path) > 1, node, avoid)
            if way is None:
                return None
            path.extend(way[1:])
            if action is not None:
                actions[len(path) - 1] = action
        return path, actions

    def _next_end(self, job: Job, e: int) -> int:
        """Return the first path index after `e` where the base may end (a stop point's way)."""
        stop = min([i for i in job.actions if i > e] + [len(job.path) - 1])
        path, passed = job.path, job.passed or e > 0
        for j in range(e + 1, stop):
            if self.graph.nodes[path[j]].stoppable \
                    and self._way(path[e], passed, path[j]) == path[e:j + 1] \
                    and self._way(path[j], True, path[stop]) == path[j:stop + 1]:
                return j
        return stop

    # -- trucks ------------------------------------------------------------------------------
    def _where(self, t: Truck) -> tuple[str, bool]:
        node = t.state.last_node_id if t.state else ''
        return (node or self.graph.start), bool(node)

    def _idle(self, t: Truck) -> bool:
        return t.state is not None and not t.broken and not t.offline \
            and (t.job is None or t.job.over) and not self._unplaced(t)

    def _unplaced(self, t: Truck) -> bool:
        """Return True for a truck set down at a position it has not been told yet."""
        return t.name in self._positions and t.state is not None and not t.state.last_node_id

    def _stalled(self, t: Truck) -> bool:
        """Return True when a truck has run out of granted way (or has not started its job)."""
        job = t.job
        if job is None or job.over:
            return False
        return not job.sent or t.pos >= job.base_end

    def _assign(self) -> None:
        """Give the queued transports, oldest first, to the nearest idle trucks."""
        while self.queue:
            transport = self.queue[0]
            pick = self._stop_of(transport.source)
            best = None
            for t in self._trucks.values():
                if not self._idle(t):
                    continue
                way = self._way(*self._where(t), pick)
                if way is not None:
                    best = min(best or (float('inf'), ''), (self.graph.length(way), t.name))
            if best is None:
                return
            t = self._trucks[best[1]]
            start, passed = self._where(t)
            drop = self._stop_of(transport.destination)
            plan = self._plan(start, passed, [
                (pick, hard_action(f'{transport.id}-pick', 'pick')),
                (drop, hard_action(f'{transport.id}-drop', 'drop'))])
            if plan is None:
                return
            self.queue.popleft()
            self.assignments[transport.id] = t.name
            t.job, t.pos = Job(transport.id, transport, plan[0], plan[1], passed), 0

    def _extend(self, t: Truck, out: list[tuple[str, str, BaseModel]]) -> None:
        """Grant what corridors can be granted and release them by an order or update."""
        job = t.job
        assert job is not None
        first = job.base_end
        stalled = self._stalled(t)
        end = first
        while end < len(job.path) - 1:
            nxt = self._next_end(job, end)
            blocks = self.reservations.corridor(t.name, job.path, end, nxt)
            if blocks is None or not self.reservations.grant(t.name, blocks, wait=False):
                break
            end = nxt
        if end == first and stalled:
            end = self._passing_place(t, job, first)
        if end == first:
            return
        job.base_end = end
        if job.sent:
            job.update_id += 1
        out.append((t.name, ORDER, order_message(self.graph, t, job, first if job.sent else 0,
                                                   self.manufacturer)))
        job.sent = True

    def _passing_place(self, t: Truck, job: Job, e: int) -> int:
        """Re-route a stalled truck to a stop marker of its next block; return the new end.

        Such a truck waits only for its next block when that block has a stop marker it can
        stand at, for the whole corridor otherwise: the wait the watchdog sees.
        """
        path = job.path
        blocks = self.reservations.corridor(t.name, path, e, self._next_end(job, e))
        if not blocks:
            return e
        passed = job.passed or e > 0
        choices = []
        for node in sorted(self.reservations.blocks[blocks[0]].nodes):
            way = self._way(path[e], passed, node)
            if self.graph.nodes[node].stoppable and way is not None \
                    and self.reservations.corridor(t.name, way, 0, len(way) - 1) == blocks[:1]:
                choices.append((self.graph.length(way), node, way))
        rest = [(path[i], job.actions.get(i))
                for i in sorted({i for i in job.actions if i > e} | {len(path) - 1})]
        plans = [(way, plan) for _, node, way in sorted(choices)
                 if (plan := self._plan(path[e], passed, [(node, None), *rest]))]
        if not plans:
            self.reservations.wait(t.name, blocks)
            return e
        if not self.reservations.grant(t.name, blocks[:1]):
            return e
        way, (new_path, actions) = plans[0]
        job.path = path[:e] + new_path
        job.actions = {i: a for i, a in job.actions.items() if i <= e}
        job.actions.update({e + i: a for i, a in actions.items()})
        return e + len(way) - 1

    def _park_or_yield(self, t: Truck, out: list[tuple[str, str, BaseModel]]) -> None:
        """Send an idle truck to its parking spot, or out of the way of a waiting truck.

        One in the way that cannot move waits for its way out in turn, so that the idle
        truck in front of it makes way too.
        """
        node, passed = self._where(t)
        wanted = set().union(*(self.reservations.waiting(o.name) for o in self._trucks.values()
                               if o is not t and (self._stalled(o) or self._idle(o))))
        in_the_way = bool(wanted & self.reservations.held(t.name))
        goals = []
        park = self.parking.get(t.name)
        if park is not None and park != node and not self.queue:
            goals.append(park)
        if in_the_way:
            ways = {n.id: self._way(node, passed, n.id) for n in self.graph.nodes.values()
                    if n.stoppable and n.id != node}
            goals.extend(sorted((n for n, w in ways.items() if w),
                                key=lambda n: (self.graph.length(ways[n] or []), n)))
        else:
            self.reservations.stop_waiting(t.name)
        corridors = [(goal, way, self.reservations.corridor(t.name, way, 0, len(way) - 1))
                     for goal in goals if (way := self._way(node, passed, goal))]
        corridors = [c for c in corridors if c[2] is not None]
        # A way through blocks the waiting trucks want is the last choice, not none.
        corridors.sort(key=lambda c: bool(in_the_way and wanted & set(c[2] or ())))
        for goal, way, blocks in corridors:
            if not self.reservations.grant(t.name, blocks or [], wait=False):
                continue
            self._serial += 1
            kind = 'park' if goal == park else 'yield'
            job = Job(f'{kind}-{t.name}-{self._serial}', None, list(way), {}, passed,
                       base_end=len(way) - 1, sent=True)
            t.job, t.pos = job, 0
            out.append((t.name, ORDER, order_message(self.graph, t, job, 0, self.manufacturer)))
            return
        if in_the_way and corridors:
            # the best corridor, all of it: its first block may be one only passed (a junction)
            self.reservations.wait(t.name, corridors[0][2] or [])


