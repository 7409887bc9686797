"""A node process killed while the truck is moving over DDS: the truck must end at rest.

Each case starts the whole graph (one process per node, config/graph.yaml), gives the executive
a task that drives along the wire, waits until the simulated truck is running at speed, then
SIGKILLs one node process: no goodbye, no last record. What must stop the truck differs:

- route_following / navigation: the executive sees the sub-system's status go stale and
  e-stops through traction (stale_status fault, reported as a failed task);
- position_sensor: navigation's ADC samples stop, it declares the sensor lost, speed 0;
- executive: traction's command goes stale and the trip latches (stale_command);
- traction: nothing computes again, so the world's trip-relay monostable drops out when the
  watchdog count stops changing (thesis appendix B.2.1) and the truck coasts to rest.

Speed is measured from /world/pose (the world's ground truth), in simulated time.
"""

from __future__ import annotations

import math
import signal
import time

import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]

CRUISE = 0.6  # m/s the truck must exceed before the kill (1983 cruise: 0.7)
AT_REST = 0.005  # m/s
REST_HOLD = 2.0  # simulated s it must stay at rest


class PoseSpeed:
    """Ground-truth speed from successive /world/pose messages (simulated time)."""

    def __init__(self) -> None:
        self.last: tuple[float, float, float] | None = None
        self.speed = 0.0
        self.time = 0.0

    def __call__(self, msg) -> None:
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        x, y = msg.pose.position.x, msg.pose.position.y
        if self.last is not None and t > self.last[0]:
            self.speed = math.hypot(x - self.last[1], y - self.last[2]) / (t - self.last[0])
        self.last, self.time = (t, x, y), t


@pytest.mark.parametrize('victim, stop_within, report', [
    ('route_following', 3.0, 'FAILED: stale status (route)'),
    ('navigation', 3.0, 'FAILED: stale status (navigation)'),
    ('position_sensor', 3.0, 'FAILED: sensor lost (navigation)'),
    ('executive', 3.0, None),  # nobody left to report; traction's trip record proves the cause
    ('traction', 5.0, 'FAILED: stale status (traction)'),
])
def test_killed_node_ends_in_a_stop(tmp_path, victim, stop_within, report):
    import os

    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.context import Context
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.launcher import Launch, Options
    from agv_nodes.records.codec import codec
    from agv_nodes.ros_ports import RecordSubscription

    launch = Launch(Options(time_factor=1.0, quiet=True, log_dir=tmp_path / 'logs',
                            domain_id=int(os.environ['ROS_DOMAIN_ID'])))
    context = Context()
    rclpy.init(context=context, domain_id=launch.domain)
    node = rclpy.create_node('kill_test', context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    speed = PoseSpeed()
    reports: list[str] = []
    node.create_subscription(PoseStamped, 'world/pose', speed, qos.STREAM_READER)
    node.create_subscription(String, 'comms/report', lambda m: reports.append(m.data),
                             qos.EVENTS)
    trips: list[str] = []
    RecordSubscription(node, codec()['traction_status'], 'e2e',
                       lambda f: trips.append(f['trip_cause']) if f['tripped'] else None)
    task_pub = node.create_publisher(String, 'comms/task', qos.EVENTS)
    launch.start()

    def spin_until(condition, wall_limit: float, what: str) -> None:
        deadline = time.monotonic() + wall_limit
        while not condition():
            executor.spin_once(timeout_sec=0.05)
            dead = [n for n in launch.poll() if n != victim]
            assert not dead, f'{dead} died while waiting for {what}'
            assert time.monotonic() < deadline, (
                f'timed out waiting for {what}; reports {reports}; '
                + '\n'.join(launch.lines[-40:]))

    try:
        spin_until(lambda: launch.moving.is_set() and task_pub.get_subscription_count() > 0,
                   120, 'the graph')
        task_pub.publish(String(data='stop at 2 second'))
        spin_until(lambda: speed.speed > CRUISE, 90, f'the truck to exceed {CRUISE} m/s')
        killed_at, speed_at_kill = speed.time, speed.speed
        launch.procs[victim].send_signal(signal.SIGKILL)
        rest = {'since': None}

        def stopped_and_held() -> bool:
            if speed.speed > AT_REST:
                rest['since'] = None
                return False
            if rest['since'] is None:
                rest['since'] = speed.time
            return speed.time - rest['since'] >= REST_HOLD

        spin_until(stopped_and_held, 120, 'the truck to stop and stay stopped')
        stopped_after = rest['since'] - killed_at
        print(f'{victim} killed at {killed_at:.2f} s sim, {speed_at_kill:.2f} m/s: at rest '
              f'{stopped_after:.2f} s later; reports {reports}')
        assert stopped_after <= stop_within, (
            f'killing {victim}: at rest only {stopped_after:.2f} s (sim) after the kill')
        if report:
            spin_until(lambda: any(report in r for r in reports), 30, f'a {report!r} report')
        else:
            assert trips and trips[-1] == 'stale_command', trips
        assert launch.procs[victim].poll() == -signal.SIGKILL
    finally:
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
        launch.stop()
