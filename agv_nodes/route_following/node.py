"""route_following (ros2 run agv_nodes route_following); hw/camera/front and rear: mono8.

With the feed-forward law (camera_law, or a leg's own) it also draws the identified track
(Rajagopalan 1991, 5.4) at VIEW_RATE while the identification has converged (the fits the law
steers by): route/identified_track, a nav_msgs/Path, and route/osculating_circle, a
visualization_msgs/Marker line strip, both in the odometry frame the track was identified in
(`odom`: the truck's pose integrated from wheel odometry, starting at the origin).

The camera truck also takes geometry_msgs/Twist on `cmd_vel` (relative; teleop_twist_keyboard's
topic), acted on only in manual mode (manual_drive.py); refused commands are counted by reason
in /diagnostics as input `cmd_vel`. It logs its 12 software channels every 50 ms of sim time on
`route/channels` (agv_nodes/channels.py; Rajagopalan 1991, 6.3.8, App. F.10).
"""

from collections import Counter
from collections.abc import Callable
import math
import sys

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped, Twist
from nav_msgs.msg import Path
import numpy as np
from sensor_msgs.msg import Image
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import Marker

from agv_nodes import channels, qos
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.sonar_input import SonarSubscription
from agv_nodes.stop_switches import FrameSubscription
from agv_nodes.track_geometry.osculating import Circle

FRAME = 'odom'
VIEW_RATE = 2.0  # Hz
CIRCLE_POINTS = 72


def track_path(points: list[tuple[float, float]], stamp: Time) -> Path:
    """route/identified_track: the identified track's points, headed along the track."""
    msg = Path()
    msg.header.stamp, msg.header.frame_id = stamp, FRAME
    for k, (x, y) in enumerate(points):
        a, b = points[max(k - 1, 0)], points[min(k + 1, len(points) - 1)]
        heading = math.atan2(b[1] - a[1], b[0] - a[0])
        pose = PoseStamped()
        pose.header = msg.header
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.z = math.sin(heading / 2.0)
        pose.pose.orientation.w = math.cos(heading / 2.0)
        msg.poses.append(pose)
    return msg


def circle_marker(circle: Circle | None, stamp: Time) -> Marker:
    """route/osculating_circle: the circle as a closed line strip; DELETE without one."""
    msg = Marker(ns='osculating_circle', id=0, type=Marker.LINE_STRIP)
    msg.header.stamp, msg.header.frame_id = stamp, FRAME
    msg.pose.orientation.w = 1.0
    if circle is None or circle.straight:  # a straight track has no circle to draw
        msg.action = Marker.DELETE
        return msg
    msg.action = Marker.ADD
    msg.scale.x = 0.02
    msg.color.a, msg.color.r, msg.color.g, msg.color.b = 1.0, 0.2, 0.8, 1.0
    for k in range(CIRCLE_POINTS + 1):
        phi = 2.0 * math.pi * k / CIRCLE_POINTS
        msg.points.append(Point(x=circle.h + circle.radius * math.cos(phi),
                                y=circle.k + circle.radius * math.sin(phi)))
    return msg


class CmdVelInput:
    """cmd_vel as /diagnostics shows an input: taken and refused by reason (inputs_report)."""

    lost, duplicate, waiting = 0, '', ''

    def __init__(self, node: 'RouteFollowingNode') -> None:
        self.name, self.stamp_ns, self.last_error = 'cmd_vel', None, ''
        self._node = node
        self._core = node.core
        # best effort: matches a reliable teleop writer and a best-effort one alike
        node.create_subscription(Twist, 'cmd_vel', self._on_twist, qos.STREAM_READER)

    @property
    def accepted(self) -> int:
        """Commands acted on."""
        return self._core.manual.taken

    @property
    def rejects(self) -> Counter[str]:
        """Commands refused, by reason."""
        return self._core.manual.refused

    @property
    def rejected(self) -> int:
        """Commands refused."""
        return sum(self.rejects.values())

    def age_s(self, now_ns: int) -> float:
        """Seconds since the last command acted on (inf if none yet)."""
        return float('inf') if self.stamp_ns is None else (now_ns - self.stamp_ns) * 1e-9

    def identity(self) -> str:
        """Say whose input this is: any writer (the ROS convention for cmd_vel)."""
        return 'any (teleop)'

    def _on_twist(self, msg: Twist) -> None:
        now = self._node.now_s()
        verdict = self._core.on_twist((msg.linear.x, msg.linear.y, msg.linear.z),
                                      (msg.angular.x, msg.angular.y, msg.angular.z), now)
        if verdict == 'taken':
            self.stamp_ns = int(now * 1e9)
        else:
            self.last_error = f'cmd_vel refused: {verdict}'


class RouteFollowingNode(CoreNode):
    """RouteCore on its ports, plus the two cameras' frames (dark tape)."""

    def __init__(self) -> None:
        super().__init__(RouteCore)
        self.channel_log: channels.ChannelLog | None = None
        for camera in ('front', 'rear'):  # from the named writer only (world, or a driver)
            frames = FrameSubscription(self, camera, qos.STREAM_READER, self._frame(camera))
            self.input_diagnostics.add(frames.name, frames)
        if self.core.p.vehicle == 'concic2':  # the front sonar (obstacle_stop.py)
            sonar = SonarSubscription(self, lambda m: self.publish(self.core.on_sonar(
                m, self.now_s())))
            self.input_diagnostics.add(sonar.name, sonar)
        if self.core.p.vehicle == 'concic2':  # the camera truck identifies its track
            self.input_diagnostics.add('cmd_vel', CmdVelInput(self))
            self.channel_log = channels.ChannelLog(self.core.p.image)
            self.channels_pub = self.create_publisher(Float64MultiArray, channels.TOPIC,
                                                      qos.STREAM_WRITER)
            self.periodic(channels.SAMPLE_PERIOD, self._log_channels)
            # Pictures that change as the truck goes, as the world's pose is.
            self.track_pub = self.create_publisher(Path, 'route/identified_track',
                                                   qos.STREAM_WRITER)
            self.circle_pub = self.create_publisher(Marker, 'route/osculating_circle',
                                                    qos.STREAM_WRITER)
            self.periodic(1.0 / VIEW_RATE, self._draw_track)

    def _frame(self, camera: str) -> Callable[[Image], None]:
        def callback(msg: Image) -> None:
            if msg.encoding != 'mono8' or msg.height * msg.width != len(msg.data):
                self.get_logger().warn(f'{camera} camera frame rejected: {msg.encoding} '
                                       f'{msg.width}x{msg.height}', throttle_duration_sec=5.0)
                return
            pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height,
                                                                              msg.width)
            frame = (pixels < 128).astype(np.uint8)  # dark tape = 1, as the optic-RAM gives it
            if self.channel_log is not None:
                self.channel_log.frame(frame, camera)
            self.publish(self.core.on_frame(frame, self.now_s(), camera))
        return callback

    def _log_channels(self) -> None:
        sample = self.channel_log.sample(self.core, self.now_s())
        self.channels_pub.publish(Float64MultiArray(data=sample))

    def _draw_track(self) -> None:
        guidance = self.core.track_guidance
        if not guidance.ready:
            return  # no fit the law would steer by (a feedback leg, or since a reset)
        stamp = self.get_clock().now().to_msg()
        points = guidance.track()
        if points:
            self.track_pub.publish(track_path(points, stamp))
        self.circle_pub.publish(circle_marker(guidance.circle, stamp))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes route_following [--ros-args ...]."""
    return spin_main(RouteFollowingNode, args)


if __name__ == '__main__':
    sys.exit(main())
