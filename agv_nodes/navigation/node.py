"""navigation: PC6/1's navigating and positioning loops (ros2 run agv_nodes navigation).

Reads navigation/command, position_sensor/status and hw/wheel_odometry; writes
navigation/status, traction/link and position_sensor/command. Behaviour:
`agv_nodes.navigation.core`; parameters: `agv_nodes.navigation.settings`.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.navigation.core import NavigationCore


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes navigation [--ros-args ...]."""
    return spin_main(lambda: CoreNode(NavigationCore), args)


if __name__ == '__main__':
    sys.exit(main())
