"""load_handling: the truck's conveyors (ros2 run agv_nodes load_handling).

Reads load/command and hw/conveyor/status; writes hw/conveyor/command and load/status.
Behaviour: `agv_nodes.load_handling.core`.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.load_handling.core import LoadHandlingCore, LoadParams
from agv_nodes.params import Parameters


class LoadHandlingNode(CoreNode):
    """Parameters -> LoadHandlingCore -> ports."""

    def __init__(self) -> None:
        super().__init__('load_handling')
        p = Parameters(self)
        lp = LoadParams(align_wait=p.number('align_wait', LoadParams().align_wait, 'seconds '
                                            'for the truck to come to rest aligned', 0.1, 60.0))
        self.attach(LoadHandlingCore(lp), p)


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes load_handling [--ros-args ...]."""
    return spin_main(LoadHandlingNode, args)


if __name__ == '__main__':
    sys.exit(main())
