"""The world node's own loop: it is the graph's clock (a mixin of WorldNode, ROS-thin).

The world does not run on a ROS timer: a sim-time timer cannot fire faster than /clock advances,
and the world is what advances it. Its loop waits until every link named in `wait_for_links` has
matched at both ends (agv_nodes/world/peers.py) and writes `ready_file`; then it steps the
core(s), publishes /clock, services its subscriptions and services between samples, and paces
itself at `time_factor` x real time (0 = as fast as the graph keeps up: it waits for any node
whose sim/progress lags, agv_nodes/world/pacing.py).

WorldLoop expects of the node: `s` (WorldNodeSettings), `members` (itself, or a floor's truck
world nodes), `floor`, `control`, `peers`, `pacer`, `time`, `_work`, `publish_clock_now` and
`publish_step`.
"""

from __future__ import annotations

from pathlib import Path
import time
from typing import Any

from agv_nodes.node_process import running


class WorldLoop:
    """Waiting for the graph, pacing and stepping (see the module docstring)."""

    def _work_done(self) -> int:
        return self._work + sum(m._work for m in self.members if m is not self)

    def drain(self, executor: Any, limit: int = 200) -> None:
        """Run every callback that is ready now (inputs, services)."""
        for _ in range(limit):
            before = self._work_done()
            executor.spin_once(timeout_sec=0.0)
            if self._work_done() == before:
                return

    def _missing(self) -> list[str]:
        nodes = [self] if self.floor is None else [self, *self.members]
        return [f'{n.get_namespace().rstrip("/")}/{link}' if n is not self else link
                for n in nodes for link in n.peers.missing()]

    def _wait_for_peers(self, executor: Any) -> bool:
        started = time.monotonic()
        while running() and self._missing():
            if self.s.publish_clock:
                self.publish_clock_now()
            executor.spin_once(timeout_sec=0.05)
            if time.monotonic() - started > self.s.peer_timeout:
                self.get_logger().error(f'peers not matched after {self.s.peer_timeout:.0f} s '
                                        f'(links still missing: {self._missing()})')
                return False
        links = sum(len(m.peers.links) for m in {self, *self.members})
        trucks = f', {len(self.members)} trucks' if self.floor is not None else ''
        self.get_logger().info(f'layout {self.layout.name}{trucks}: moving at time_factor '
                               f'{self.s.time_factor:g} ({links} links matched '
                               f'at both ends after {time.monotonic() - started:.2f} s)')
        if self.s.ready_file:
            Path(self.s.ready_file).write_text(f'moving at sim time {self.time:.3f} s\n')
        return True

    def _lagging(self) -> list[str]:
        now = self.time
        return [f'{m.get_namespace().rstrip("/")}/{node}'.lstrip('/') for m in self.members
                for node in m.pacer.lagging(now)]

    def _catch_up(self, executor: Any) -> None:
        """Let lagging nodes catch up before time moves on (at most lag_patience).

        start_patience instead while a lagging node has not been heard from since the world
        started moving (agv_nodes/world/pacing.py).
        """
        late = self._lagging()
        waited = time.monotonic()
        nudge = waited + 0.05
        now = self.time
        starting = any(m.pacer.unheard(m.pacer.lagging(now)) for m in self.members)
        patience = max(self.s.start_patience, self.s.lag_patience) if starting \
            else self.s.lag_patience
        while late and running() and time.monotonic() - waited < patience:
            executor.spin_once(timeout_sec=0.002)
            late = self._lagging()
            if late and self.s.publish_clock and time.monotonic() > nudge:
                # The same time again: a node that missed the last /clock gets another look;
                # timers that already ran at this time do not run twice.
                self.publish_clock_now()
                nudge = time.monotonic() + 0.05
        if late and running():  # (not when a stop request ended the wait)
            for m in self.members:
                m.pacer.give_up(m.pacer.lagging(self.time))
            self.get_logger().warn(f'carrying on without {", ".join(late)} (behind for '
                                   f'{patience:g} s)')

    def _report_pacing(self) -> None:
        """Log how far behind the world each node was heard at worst over the last minute."""
        worst = ', '.join(f'{m.get_namespace().rstrip("/")}/{name}'.lstrip('/')
                          + f' {s * 1000:.0f} ms' for m in self.members
                          for name, s in sorted(m.pacer.worst.items()))
        self.get_logger().info(f'pacing, the last minute: worst behind {worst or "-"}')
        for m in self.members:
            m.pacer.worst.clear()

    def step_all(self) -> None:
        """One sample: /clock, every truck's world, then (a floor) the contacts between them."""
        outs = [m.core.step() for m in self.members]
        if self.s.publish_clock and self.members[0].core.sample % self.s.clock_every == 0:
            self.publish_clock_now()
        for m, out in zip(self.members, outs, strict=True):
            m.publish_step(out)
        if self.floor is not None:
            self.floor.contacts()

    def run(self, executor: Any) -> int:
        """Wait for peers, then step the world until shut down (or `duration`)."""
        for m in self.members:
            if m is not self:
                executor.add_node(m)
        if not self._wait_for_peers(executor):
            return 1
        wall0, sim0 = time.monotonic(), self.time
        for m in self.members:
            m.pacer.start(self.time)
        report_at = self.time + 60.0
        control = self.control
        while running():
            if self.time >= report_at:
                report_at += 60.0
                self._report_pacing()
            self.drain(executor)
            if control.paused and control.step_requests == 0:
                executor.spin_once(timeout_sec=0.02)
                wall0, sim0 = time.monotonic(), self.time
                continue
            if self._lagging():
                self._catch_up(executor)
                wall0, sim0 = time.monotonic(), self.time
                if control.paused and control.step_requests == 0:
                    continue  # paused while it waited: not one sample past the pause's time
            if control.step_requests:
                control.step_requests -= 1
            self.step_all()
            if self.s.duration and self.time >= self.s.duration:
                self.get_logger().info(f'duration {self.s.duration:g} s reached')
                return 0
            if self.s.time_factor > 0:
                ahead = (self.time - sim0) / self.s.time_factor - (time.monotonic() - wall0)
                if ahead > 0:
                    time.sleep(ahead)
        return 0
