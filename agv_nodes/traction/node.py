"""traction: the only node that moves the truck (ros2 run agv_nodes traction; traction.core)."""

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.traction.core import TractionCore


class TractionNode(CoreNode):
    """TractionCore on its ports, and the trip relay's story in the log."""

    def __init__(self) -> None:
        super().__init__(TractionCore)
        self._was_tripped: str | None = 'startup'

    def _tick(self) -> None:
        super()._tick()
        now = self.core.trip_cause if self.core.tripped else None
        if now != self._was_tripped:
            if now is None:
                self.get_logger().info('trip relay reset (00H then a demand)')
            else:
                self.get_logger().warn(f'trip relay open: {now}')
            self._was_tripped = now


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes traction [--ros-args ...]."""
    return spin_main(TractionNode, args)


if __name__ == '__main__':
    sys.exit(main())
