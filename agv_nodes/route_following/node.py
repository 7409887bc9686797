"""route_following (ros2 run agv_nodes route_following); hw/camera/front: mono8, dark tape."""

import sys

import numpy as np
from sensor_msgs.msg import Image

from agv_nodes import qos
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.route_following.core import RouteCore


class RouteFollowingNode(CoreNode):
    """RouteCore on its ports, plus the camera frames."""

    def __init__(self) -> None:
        super().__init__(RouteCore)
        self.create_subscription(Image, 'hw/camera/front', self._frame, qos.STREAM_READER)

    def _frame(self, msg: Image) -> None:
        if msg.encoding != 'mono8' or msg.height * msg.width != len(msg.data):
            self.get_logger().warn(f'camera frame rejected: {msg.encoding} '
                                   f'{msg.width}x{msg.height}', throttle_duration_sec=5.0)
            return
        pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width)
        frame = (pixels < 128).astype(np.uint8)  # dark tape = 1, as the optic-RAM gives it
        self.publish(self.core.on_frame(frame, self.now_s()))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes route_following [--ros-args ...]."""
    return spin_main(RouteFollowingNode, args)


if __name__ == '__main__':
    sys.exit(main())
