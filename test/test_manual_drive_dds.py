"""Manual mode over DDS: the camera truck driven from cmd_vel as teleop_twist_keyboard drives it.

The real graph (world, route following, executive, communications, each its own process) on
junction_1991, in real time (time_factor 1, so a teleop's 10 Hz is 10 Hz of sim time). The
teleop is a plain rclpy node publishing geometry_msgs/Twist on the relative topic `cmd_vel`
with teleop_twist_keyboard's QoS (reliable, keep last 10), one Twist each 0.1 s of sim time as
a held key repeats. Ground truth is the world's: /world/pose and its drive_off events. Checked:
a Twist before the manual task is refused and counted in /diagnostics, never acted on; in the
task the truck goes at the Twist's speed and yaw rate; the Twists falling silent stop it no
sooner than manual.timeout after the last one and it stays at rest; the E-stop wins over a
held key and fails the task naming it.
"""

from __future__ import annotations

import math

from graph_probe import GraphProbe
import pytest

from agv_nodes.route_following.settings import ManualParams, RouteParams

pytestmark = [pytest.mark.dds, pytest.mark.slow]

LAYOUT = 'junction_1991'
TELEOP = 0.1  # s of sim time between Twists
TIMEOUT = ManualParams().timeout  # s, the declared cmd_vel watchdog
DT = 1.0 / 340  # s, one world sample
ROUTE_PERIOD = RouteParams().period


class Teleop:
    """A teleop_twist_keyboard stand-in on the probe's ROS context, paced by sim time."""

    def __init__(self, g: GraphProbe) -> None:
        from geometry_msgs.msg import PoseStamped, Twist
        import rclpy
        from rclpy.qos import QoSProfile

        from agv_nodes import qos

        self.g, self.twist_type = g, Twist
        self.node = rclpy.create_node('teleop_twist_keyboard', context=g.context)
        g.executor.add_node(self.node)
        self.pub = self.node.create_publisher(Twist, 'cmd_vel', QoSProfile(depth=10))
        self.heading = 0.0
        self.headings: list[tuple[float, float]] = []  # (sim t, heading) from /world/pose
        g.node.create_subscription(PoseStamped, 'world/pose', self._pose, qos.STREAM_READER)
        self.sent_at: list[float] = []  # the probe's sim time at each Twist

    def _pose(self, msg) -> None:
        q = msg.pose.orientation
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        heading = 2.0 * math.atan2(q.z, q.w)
        if self.headings:  # unwrapped
            heading += round((self.headings[-1][1] - heading) / (2 * math.pi)) * 2 * math.pi
        self.headings.append((t, heading))

    def hold(self, seconds: float, linear: float, angular: float) -> None:
        """Publish the Twist each TELEOP s of sim time for `seconds` of sim time."""
        g, end = self.g, self.g.time + seconds
        msg = self.twist_type()
        msg.linear.x, msg.angular.z = float(linear), float(angular)
        while g.time < end:
            self.pub.publish(msg)
            self.sent_at.append(g.time)
            g.spin_until(lambda due=g.time + TELEOP: g.time >= due, 30, 'sim time to pass')

    def yaw_rate(self, t0: float, t1: float) -> float:
        """Ground-truth yaw rate between sim times t0 and t1 (rad/s)."""
        a = next(p for p in self.headings if p[0] >= t0)
        b = [p for p in self.headings if p[0] <= t1][-1]
        return (b[1] - a[1]) / (b[0] - a[0])

    def close(self) -> None:
        self.node.destroy_node()


def speed_between(g: GraphProbe, t0: float, t1: float) -> float:
    """Ground-truth mean speed along the path between sim times t0 and t1 (m/s)."""
    pts = [(t, x, y) for t, x, y in g.path if t0 <= t <= t1]
    length = sum(math.dist(a[1:], b[1:]) for a, b in zip(pts, pts[1:], strict=False))
    return length / (pts[-1][0] - pts[0][0])


@pytest.mark.timeout(300)
def test_cmd_vel_drives_in_manual_mode_only_and_its_silence_stops_the_truck(tmp_path) -> None:
    g = GraphProbe(tmp_path / 'logs', layout=LAYOUT, time_factor=1.0)
    teleop = Teleop(g)
    try:
        g.ready()
        # before any manual task: refused, counted by reason, the truck stays where it is
        start = g.path[-1]
        teleop.hold(1.0, 0.3, 0.0)
        g.spin_until(lambda: g.counted('route_following', 'cmd_vel rejected') >= 10, 30,
                     'the refusals in /diagnostics')
        assert g.inputs['route_following']['cmd_vel rejects by reason'] == \
            f'not_manual={g.counted("route_following", "cmd_vel rejected")}'
        assert g.counted('route_following', 'cmd_vel accepted') == 0
        assert math.dist(g.path[-1][1:], start[1:]) < 1e-6
        g.start_task('manual', cruise=None)
        g.report_with("'manual': running")
        # driven: 3 s to set off (the drive's 0.3 m/s^2 ramp), then 3 s measured
        teleop.hold(3.0, 0.3, 0.25)
        t0 = g.time
        teleop.hold(3.0, 0.3, 0.25)
        t1 = g.time - 0.2  # the last pose the probe may have before the next Twist
        assert speed_between(g, t0, t1) == pytest.approx(0.3, abs=0.003)
        assert teleop.yaw_rate(t0, t1) == pytest.approx(0.25, abs=0.01)
        # silence: the motors go off no sooner than the timeout after the last Twist
        last = teleop.sent_at[-1]
        rest = g.stays_at_rest(hold=2.0, wall_limit=60)
        cut = g.drive_off_after(last)
        assert cut is not None and TIMEOUT <= cut <= TIMEOUT + 0.5, cut
        assert rest - last < TIMEOUT + 0.5 + 0.3 / 2.6 + 0.1
        assert not any('FAILED' in r for r in g.reports), g.reports  # still in manual mode
        # the next Twist drives again; an abort ends the mode and stops the truck
        teleop.hold(2.0, 0.2, 0.0)
        assert g.speed > 0.1
        g.task_pub.publish(_text('abort'))
        g.report_with("'abort': completed")
        teleop.hold(2.0, 0.2, 0.0)  # held on after the abort: refused again
        assert g.speed <= 0.005
        g.spin_until(lambda: 'not_manual' in g.inputs['route_following'].get(
            'cmd_vel rejects by reason', ''), 30, 'the refusals after the abort')
    finally:
        teleop.close()
        g.close()


@pytest.mark.timeout(300)
def test_the_estop_wins_over_a_held_key(tmp_path) -> None:
    g = GraphProbe(tmp_path / 'logs', layout=LAYOUT, time_factor=1.0)
    teleop = Teleop(g)
    try:
        g.start_task('manual', cruise=None)
        g.report_with("'manual': running")
        teleop.hold(4.0, 0.4, 0.0)
        assert g.speed == pytest.approx(0.4, abs=0.01)
        at = g.at_exact_time(lambda: g.set_world(**{'concic2.estop': True}))
        teleop.hold(3.0, 0.4, 0.0)  # the key held down through the stop
        g.drive_off_ms(at, 2 * DT + 0.001)  # the PAL cuts the amplifiers at once
        g.report_with('FAILED: drive fault (route): estop')
        assert g.speed <= 0.005
        assert g.travelled_since(at) < 0.4 * 2 * DT + 0.4 ** 2 / (2 * 2.6) + 0.01
        g.stays_at_rest(hold=2.0)
        teleop.hold(2.0, 0.4, 0.0)  # and on after the task failed: never acted on
        assert g.speed <= 0.005
    finally:
        teleop.close()
        g.close()


def _text(words: str):
    from std_msgs.msg import String

    return String(data=words)
