"""navigation: PC6/1's navigating and positioning loops (ros2 run agv_nodes navigation)."""

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.navigation.core import NavigationCore


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes navigation [--ros-args ...]."""
    return spin_main(lambda: CoreNode(NavigationCore), args)


if __name__ == '__main__':
    sys.exit(main())
