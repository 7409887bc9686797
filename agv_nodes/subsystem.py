"""SubsystemCore: what every sub-system core is to its node and to the lock-step harness.

A core is ROS-free: told records, rejections and the time, it returns the records to send. Its
class names the node (msg_schemas' writer/readers), its settings dataclass and its timer's period
setting. What it says in words goes through its `Notes`, which its node takes after each call and
logs (communications also publishes them on comms/report); both queues are bounded.
"""

from collections import deque
from dataclasses import dataclass
from typing import Any


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


class SubsystemCore:
    """The common part of the seven cores; subclasses set the three class attributes."""

    node: str = ''  # its name in msg_schemas (writer / readers) and as a ROS node
    settings_type: type = object  # its settings dataclass
    period_setting: str = 'period'  # the setting holding the timer's period, s

    def __init__(self, params: Any = None) -> None:
        self.p = params if params is not None else self.settings_type()
        self.period: float | None = getattr(self.p, self.period_setting)
        # a second, faster timer for a core that checks something between its passes
        self.supervision_period: float | None = None
        self.notes = Notes()  # what it says in words (its node logs them)

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """Take an accepted input record; return records to send (or None)."""
        raise NotImplementedError

    def tick(self, now: float) -> dict | None:
        """Run the timer, every `period` s; return records to send (or None)."""
        raise NotImplementedError

    def supervise(self, now: float) -> dict | None:
        """Run the second timer, every `supervision_period` s (when not None)."""
        return None

    def on_writer_restart(self, record: str, now: float) -> dict | None:
        """Hear that `record`'s writer started afresh (its next record follows at once)."""
        return None
