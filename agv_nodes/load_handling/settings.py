"""Load handling settings: every parameter of the load_handling node, its default and meaning."""

from __future__ import annotations

from dataclasses import dataclass

from agv_nodes.settings import setting


@dataclass
class LoadParams:
    """The conveyor transfers (Baker 1983, 3.5.3, 6.3.2)."""

    period: float = setting(0.050, 'seconds between load_status and conveyor_command records',
                            lo=0.01, hi=1.0)
    align_wait: float = setting(3.0, 'seconds for the truck to come to rest aligned with a '
                                'workstation before the transfer fails', lo=0.1, hi=60.0)
