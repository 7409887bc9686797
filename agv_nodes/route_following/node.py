"""route_following (ros2 run agv_nodes route_following); hw/camera/front and rear: mono8."""

from collections.abc import Callable
import sys

import numpy as np
from sensor_msgs.msg import Image

from agv_nodes import qos
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.route_following.core import RouteCore


class RouteFollowingNode(CoreNode):
    """RouteCore on its ports, plus the two cameras' frames (dark tape)."""

    def __init__(self) -> None:
        super().__init__(RouteCore)
        for camera in ('front', 'rear'):
            self.create_subscription(Image, f'hw/camera/{camera}', self._frame(camera),
                                     qos.STREAM_READER)

    def _frame(self, camera: str) -> Callable[[Image], None]:
        def callback(msg: Image) -> None:
            if msg.encoding != 'mono8' or msg.height * msg.width != len(msg.data):
                self.get_logger().warn(f'{camera} camera frame rejected: {msg.encoding} '
                                       f'{msg.width}x{msg.height}', throttle_duration_sec=5.0)
                return
            pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height,
                                                                              msg.width)
            frame = (pixels < 128).astype(np.uint8)  # dark tape = 1, as the optic-RAM gives it
            self.publish(self.core.on_frame(frame, self.now_s(), camera))
        return callback


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes route_following [--ros-args ...]."""
    return spin_main(RouteFollowingNode, args)


if __name__ == '__main__':
    sys.exit(main())
