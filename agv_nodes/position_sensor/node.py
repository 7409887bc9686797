"""position_sensor: marker recognition from ADC snapshots (ros2 run agv_nodes position_sensor)."""

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.position_sensor.core import PositionSensorCore


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes position_sensor [--ros-args ...]."""
    return spin_main(lambda: CoreNode(PositionSensorCore), args)


if __name__ == '__main__':
    sys.exit(main())
