"""The world node's own loop: it is the graph's clock (a part of WorldNode, ROS-thin).

The world does not run on a ROS timer: a sim-time timer cannot fire faster than /clock advances,
and the world is what advances it. Its loop waits until every link named in `wait_for_links` has
matched at both ends (agv_nodes/world/peers.py) and writes `ready_file`; then it steps the
core(s), publishes /clock, services its subscriptions and services between samples, and paces
itself at `time_factor` x real time (0 = as fast as the graph keeps up: it waits for any node
whose sim/progress lags, agv_nodes/world/pacing.py).

The loop is a part the world node owns (`WorldLoop(node)`); what it asks of the node is written
out as `LoopHost` (and of each truck's world node as `TruckWorld`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
import time
from typing import Any, Protocol

from agv_nodes.node_process import running
from agv_nodes.world.core import WorldCore
from agv_nodes.world.floor import Control, Floor
from agv_nodes.world.pacing import GraphPacer
from agv_nodes.world.peers import LinkWatch
from agv_nodes.world.settings import WorldNodeSettings


class Watched(Protocol):
    """A world node whose links the loop waits for."""

    peers: LinkWatch

    def get_namespace(self) -> str:
        """Return the node's namespace (names a floor's truck in log lines)."""
        ...


class TruckWorld(Watched, Protocol):
    """What the loop asks of one truck's world node (a floor's member, or the node alone)."""

    core: WorldCore | None
    pacer: GraphPacer
    work: int  # callbacks it has run: the loop drains until this stops growing

    def publish_step(self, out: dict[str, Any]) -> None:
        """Publish what one core step produced."""
        ...


class LoopHost(Watched, Protocol):
    """What the loop asks of the world node that owns it (the floor's own node, or the truck's).

    Attributes, not properties, where the node has plain attributes (a Protocol's attributes are
    read and written, so their types must match the node's exactly).
    """

    s: WorldNodeSettings
    members: Sequence[TruckWorld]
    floor: Floor | None
    control: Control
    layout: Any
    work: int

    @property
    def time(self) -> float:
        """Sim time of the trucks' world (s)."""
        ...

    def get_logger(self) -> Any:
        """Return the node's logger."""
        ...

    def publish_clock_now(self) -> None:
        """Publish /clock at the current sim time."""
        ...


class WorldLoop:
    """Waiting for the graph, pacing and stepping (see the module docstring)."""

    def __init__(self, node: LoopHost) -> None:
        self.node = node

    @property
    def members(self) -> Sequence[TruckWorld]:
        """The trucks' world nodes the loop steps."""
        return self.node.members

    def _work_done(self) -> int:
        node = self.node
        return node.work + sum(m.work for m in self.members if m is not node)

    def drain(self, executor: Any, limit: int = 200) -> None:
        """Run every callback that is ready now (inputs, services)."""
        for _ in range(limit):
            before = self._work_done()
            executor.spin_once(timeout_sec=0.0)
            if self._work_done() == before:
                return

    def _watched(self) -> list[Watched]:
        """Return the node and, on a floor, every truck's world node (each has links)."""
        node = self.node
        return [node] if node.floor is None else [node, *self.members]

    def _missing(self) -> list[str]:
        node = self.node
        return [f'{n.get_namespace().rstrip("/")}/{link}' if n is not node else link
                for n in self._watched() for link in n.peers.missing()]

    def _wait_for_peers(self, executor: Any) -> bool:
        node, s = self.node, self.node.s
        started = time.monotonic()
        while running() and self._missing():
            if s.publish_clock:
                node.publish_clock_now()
            executor.spin_once(timeout_sec=0.05)
            if time.monotonic() - started > s.peer_timeout:
                node.get_logger().error(f'peers not matched after {s.peer_timeout:.0f} s '
                                        f'(links still missing: {self._missing()})')
                return False
        links = sum(len(n.peers.links) for n in self._watched())
        trucks = f', {len(self.members)} trucks' if node.floor is not None else ''
        node.get_logger().info(f'layout {node.layout.name}{trucks}: moving at time_factor '
                               f'{s.time_factor:g} ({links} links matched '
                               f'at both ends after {time.monotonic() - started:.2f} s)')
        if s.ready_file:
            Path(s.ready_file).write_text(f'moving at sim time {node.time:.3f} s\n')
        return True

    def _lagging(self) -> list[str]:
        now = self.node.time
        return [f'{m.get_namespace().rstrip("/")}/{name}'.lstrip('/') for m in self.members
                for name in m.pacer.lagging(now)]

    def _catch_up(self, executor: Any) -> None:
        """Let lagging nodes catch up before time moves on (at most lag_patience).

        start_patience instead while a lagging node has not been heard from since the world
        started moving (agv_nodes/world/pacing.py).
        """
        node, s = self.node, self.node.s
        late = self._lagging()
        waited = time.monotonic()
        nudge = waited + 0.05
        now = node.time
        starting = any(m.pacer.unheard(m.pacer.lagging(now)) for m in self.members)
        patience = max(s.start_patience, s.lag_patience) if starting else s.lag_patience
        while late and running() and time.monotonic() - waited < patience:
            executor.spin_once(timeout_sec=0.002)
            late = self._lagging()
            if late and s.publish_clock and time.monotonic() > nudge:
                # The same time again: a node that missed the last /clock gets another look;
                # timers that already ran at this time do not run twice.
                node.publish_clock_now()
                nudge = time.monotonic() + 0.05
        if late and running():  # (not when a stop request ended the wait)
            for m in self.members:
                m.pacer.give_up(m.pacer.lagging(node.time))
            node.get_logger().warn(f'carrying on without {", ".join(late)} (behind for '
                                   f'{patience:g} s)')

    def _report_pacing(self) -> None:
        """Log how far behind the world each node was heard at worst over the last minute."""
        worst = ', '.join(f'{m.get_namespace().rstrip("/")}/{name}'.lstrip('/')
                          + f' {lag * 1000:.0f} ms' for m in self.members
                          for name, lag in sorted(m.pacer.worst.items()))
        self.node.get_logger().info(f'pacing, the last minute: worst behind {worst or "-"}')
        for m in self.members:
            m.pacer.worst.clear()

    def step_all(self) -> None:
        """One sample: /clock, every truck's world, then (a floor) the contacts between them."""
        node, s = self.node, self.node.s
        cores = [_core(m) for m in self.members]
        outs = [core.step() for core in cores]
        if s.publish_clock and cores[0].sample % s.clock_every == 0:
            node.publish_clock_now()
        for m, out in zip(self.members, outs, strict=True):
            m.publish_step(out)
        if node.floor is not None:
            node.floor.contacts()

    def run(self, executor: Any) -> int:
        """Wait for peers, then step the world until shut down (or `duration`)."""
        node, s = self.node, self.node.s
        for m in self.members:
            if m is not node:
                executor.add_node(m)
        if not self._wait_for_peers(executor):
            return 1
        wall0, sim0 = time.monotonic(), node.time
        for m in self.members:
            m.pacer.start(node.time)
        report_at = node.time + 60.0
        control = node.control
        while running():
            if node.time >= report_at:
                report_at += 60.0
                self._report_pacing()
            self.drain(executor)
            if control.paused and control.step_requests == 0:
                executor.spin_once(timeout_sec=0.02)
                wall0, sim0 = time.monotonic(), node.time
                continue
            if self._lagging():
                self._catch_up(executor)
                wall0, sim0 = time.monotonic(), node.time
                if control.paused and control.step_requests == 0:
                    continue  # paused while it waited: not one sample past the pause's time
            if control.step_requests:
                control.step_requests -= 1
            self.step_all()
            if s.duration and node.time >= s.duration:
                node.get_logger().info(f'duration {s.duration:g} s reached')
                return 0
            if s.time_factor > 0:
                ahead = (node.time - sim0) / s.time_factor - (time.monotonic() - wall0)
                if ahead > 0:
                    time.sleep(ahead)
        return 0


def _core(member: TruckWorld) -> WorldCore:
    """Return a truck world node's core (every member has one; a floor's own node has none)."""
    if member.core is None:
        raise RuntimeError(f'world node {member.get_namespace()} has no world core')
    return member.core
