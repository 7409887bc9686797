"""Communications settings: every parameter of the node, its default and meaning."""

from __future__ import annotations

from dataclasses import dataclass

from agv_nodes.settings import setting


@dataclass
class CommsParams:
    """The task queue and its relay to the executive."""

    period: float = setting(0.100, 'seconds between comms_status records', lo=0.01, hi=1.0)
    locations: tuple[int, ...] = setting((0, 1, 2, 3), 'location marker identities on the '
                                         'floor: a task naming another is rejected', lo=0,
                                         hi=31)
