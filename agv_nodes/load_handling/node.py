"""load_handling: the truck's conveyors (ros2 run agv_nodes load_handling).

Reads load/command and hw/conveyor/status; writes hw/conveyor/command and load/status.
Behaviour: `agv_nodes.load_handling.core`; parameters: `agv_nodes.load_handling.settings`.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.load_handling.core import LoadHandlingCore


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes load_handling [--ros-args ...]."""
    return spin_main(lambda: CoreNode(LoadHandlingCore), args)


if __name__ == '__main__':
    sys.exit(main())
