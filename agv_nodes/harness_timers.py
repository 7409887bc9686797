"""The lock-step harness's timer dispatch: each node core's tick and supervise as they come due.

Kept apart from agv_nodes.harness, which steps the world and delivers the records; this is the
part every world sample passes through, so the clock tests come before any look-up on a core.
"""

from collections.abc import Callable, Iterable
import math
from typing import Any


def fire_timers(members: Iterable[Any], publish: Callable[[Any, dict | None], None],
                now: float) -> float:
    """Run every member's tick, then its supervise, as often as they have come due by `now`.

    `members`: the harness's `_Member`s (core, next_tick, next_supervise); `publish(member,
    outputs)` sends what a timer returns, at once, before the next timer runs. Returns when the
    next timer is due: no sample before it need call again (most samples fire none).
    """
    due = now + 1e-12
    following = math.inf
    for m in members:
        # Most samples fire no timer: the member's own clock is tested before its core.
        while m.next_tick <= due and m.core.period is not None:
            m.next_tick += m.core.period
            publish(m, m.core.tick(now))
        if m.next_supervise <= due:
            every = getattr(m.core, 'supervision_period', None)
            if every is None:  # no second timer: not looked for again (a restart resets it)
                m.next_supervise = math.inf
            while every is not None and m.next_supervise <= due:
                m.next_supervise += every
                publish(m, m.core.supervise(now))
        if m.core.period is not None and m.next_tick < following:
            following = m.next_tick
        if m.next_supervise < following:
            following = m.next_supervise
    return following
