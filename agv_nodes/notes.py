"""Notes: what a core has to say in words, the one way it hands text to its node (ROS-free).

A core adds a note (sim time, text, level); its node takes the new ones after each call into
the core and logs them (communications also publishes them on comms/report). The last `keep`
notes stay readable for tests and displays; both queues are bounded, so a long run never grows.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass


@dataclass(frozen=True)
class Note:
    """One thing a core said."""

    time: float
    text: str
    level: str = 'info'  # info | warn


class Notes:
    """A core's notes: new ones until its node takes them, and the most recent ones."""

    def __init__(self, keep: int = 500) -> None:
        self._new: deque[Note] = deque(maxlen=keep)
        self.recent: deque[Note] = deque(maxlen=keep)

    def add(self, now: float, text: str, level: str = 'info') -> None:
        """Say `text` at sim time `now`."""
        note = Note(now, text, level)
        self._new.append(note)
        self.recent.append(note)

    def take(self) -> list[Note]:
        """Return the notes added since the last take, oldest first."""
        out = list(self._new)
        self._new.clear()
        return out

    def texts(self) -> list[str]:
        """Return the recent notes' texts, oldest first."""
        return [n.text for n in self.recent]
