"""The clock-jump rule: the genuine /clock going back, or too far forward, is a fault (ROS-free).

The world steps /clock by `clock_every / sample_rate` (8.8 ms as agv-launch runs it, 2.9 ms at
the world's defaults), never back and never by more. A /clock that goes back, or forward by more
than `clock_jump_limit` between two consecutive samples of its writer, is a fault of the clock,
not of any node: without this rule a node would take a forward jump for every input's silence
(the executive's stale_status, traction's stale_command) and a backward one would hold every
timeout off until time caught up again.

Consecutive means consecutive in the writer's stream: the DDS publication sequence number says
how many samples the writer sent since the last one this reader took. A reader that lost samples
(its process frozen or starved past the writer's history) sees time move by many steps at once,
which is not a jump: the limit applies per sample sent. Where no sequence number can be had, each
sample counts as one.

A jump is absorbed, not followed: the node's time stands still across it (`offset_ns` grows by
the jump) and runs on from there at the writer's pace, so that no timeout fires for it and none
is held off by it. The jump itself is named (`Jump.text`) and the node acts on it (the executive
fails the task, traction opens its trip relay: agv_nodes/core_node.py).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Jump:
    """One jump of the writer's clock: from `before_ns` to `after_ns` (writer's time)."""

    before_ns: int
    after_ns: int

    @property
    def back(self) -> bool:
        """True for a jump back in time."""
        return self.after_ns < self.before_ns

    def text(self) -> str:
        """Say what jumped: 'clock jumped back from 12.000 s to 7.000 s'."""
        return (f'clock jumped {"back" if self.back else "forward"} from '
                f'{self.before_ns * 1e-9:.3f} s to {self.after_ns * 1e-9:.3f} s')


class ClockJumpRule:
    """Judges each /clock sample of the genuine writer; the node's time across jumps.

    `take(writer_ns, sequence)` returns the node's time for the sample (the writer's less
    `offset_ns`); `jump` is the Jump the sample made, else None.
    """

    def __init__(self, limit_s: float) -> None:
        self.limit_ns = round(limit_s * 1e9)
        self.last_ns: int | None = None  # the writer's time at its last sample
        self._last_sequence = 0  # its publication sequence number (0: none known)
        self.offset_ns = 0  # writer's time - node's time: the jumps absorbed
        self.jump: Jump | None = None  # what the last sample did
        self.jumps: list[Jump] = []  # every jump, first first

    def take(self, writer_ns: int, sequence: int = 0) -> int:
        """Take one sample of the writer (`sequence` 0: unknown); return the node's time (ns)."""
        last, last_sequence = self.last_ns, self._last_sequence
        self.last_ns, self._last_sequence = writer_ns, sequence
        self.jump = None
        if last is not None:
            step = writer_ns - last
            sent = sequence - last_sequence if sequence > last_sequence > 0 else 1
            if step < 0 or step > self.limit_ns * sent:
                self.jump = Jump(last, writer_ns)
                self.jumps.append(self.jump)
                self.offset_ns += step
        return writer_ns - self.offset_ns

    def restart(self) -> None:
        """Take up a restarted writer (a new endpoint): its sequence numbers start afresh."""
        self._last_sequence = 0
