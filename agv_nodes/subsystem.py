"""SubsystemCore: what every sub-system core is to its node and to the lock-step harness.

A core is ROS-free: it is told records, rejections and the time, and returns the records to
send. Its class names the node (the writer/readers of msg_schemas), its settings dataclass
(agv_nodes/settings.py) and the setting that is its timer's period.
"""

from __future__ import annotations

from typing import Any

from agv_nodes.notes import Notes


class SubsystemCore:
    """The common part of the seven cores; subclasses set the three class attributes."""

    node: str = ''  # its name in msg_schemas (writer / readers) and as a ROS node
    settings_type: type = object  # its settings dataclass
    period_setting: str = 'period'  # the setting holding the timer's period, s

    def __init__(self, params: Any = None) -> None:
        self.p = params if params is not None else self.settings_type()
        self.period: float | None = getattr(self.p, self.period_setting)
        self.notes = Notes()  # what it says in words (its node logs them)

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """Take an accepted input record; return records to send (or None)."""
        raise NotImplementedError

    def tick(self, now: float) -> dict | None:
        """Run the timer, every `period` s; return records to send (or None)."""
        raise NotImplementedError
