"""A test's window on a fleet over DDS: N trucks launched on one floor, each truck watched.

The probe has one rclpy node per truck, in that truck's namespace, so each sees the topics of
its own truck under the names a single truck's probe uses: world/pose, comms/report,
comms/task and world/events.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any


class TruckWatch:
    """One truck's pose, reports and world events, and its task writer."""

    def __init__(self, node: Any) -> None:
        from geometry_msgs.msg import PoseStamped
        from std_msgs.msg import String

        from agv_nodes import qos
        from agv_nodes.records.codec import codec
        from agv_nodes.ros_ports import RecordSubscription

        self.node = node
        self.speed = 0.0
        self.moved = 0.0  # m travelled
        self.time = 0.0
        self._last: tuple[float, float, float] | None = None
        self.reports: list[str] = []
        self.events: list[dict] = []
        node.create_subscription(PoseStamped, 'world/pose', self._pose, qos.STREAM_READER)
        node.create_subscription(String, 'comms/report', lambda m: self.reports.append(m.data),
                                 qos.EVENTS)
        self._events = RecordSubscription(node, codec()['world_event'], 'e2e',
                                          self.events.append)
        self.task_pub = node.create_publisher(String, 'comms/task', qos.EVENTS)

    def _pose(self, msg: Any) -> None:
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        x, y = msg.pose.position.x, msg.pose.position.y
        if self._last is not None and t > self._last[0]:
            step = math.hypot(x - self._last[1], y - self._last[2])
            self.speed, self.moved = step / (t - self._last[0]), self.moved + step
        self._last, self.time = (t, x, y), t

    def send(self, text: str) -> None:
        """Send a task on this truck's comms/task."""
        from std_msgs.msg import String

        self.task_pub.publish(String(data=text))

    def finished(self) -> bool:
        """Return True once a task has completed or failed."""
        return any(': completed' in r or 'FAILED' in r for r in self.reports)


class FleetProbe:
    """The launched fleet plus a watch per truck; `close()` shuts both down."""

    def __init__(self, log_dir: Any, trucks: int, **options: Any) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        from agv_nodes.graph.parameters import Options, fleet_names
        from agv_nodes.graph.supervisor import Launch

        self.launch = Launch(Options(**{'time_factor': 0.0, 'quiet': True, 'log_dir': log_dir,
                                        'domain_id': int(os.environ['ROS_DOMAIN_ID']),
                                        'trucks': trucks, **options}))
        self.context = Context()
        rclpy.init(context=self.context, domain_id=self.launch.domain)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.trucks: dict[str, TruckWatch] = {}
        for name in fleet_names(self.launch.o):
            node = rclpy.create_node('probe', namespace=f'/{name}', context=self.context)
            self.executor.add_node(node)
            self.trucks[name] = TruckWatch(node)
        self.launch.start()

    def spin_until(self, condition: Any, wall_limit: float, what: str) -> None:
        """Spin until `condition()`; fail on a timeout or a dead node."""
        deadline = time.monotonic() + wall_limit
        while not condition():
            self.executor.spin_once(timeout_sec=0.05)
            assert not self.launch.poll(), f'nodes died while waiting for {what}'
            assert time.monotonic() < deadline, (
                f'timed out waiting for {what}; reports '
                f'{ {n: t.reports for n, t in self.trucks.items()} }; '
                + '\n'.join(self.launch.lines[-40:]))

    def ready(self) -> None:
        """Wait until the floor moves and every truck's communications answers."""
        from agv_nodes.demo import comms_handshake

        self.spin_until(lambda: self.launch.moving.is_set() and all(
            t.task_pub.get_subscription_count() > 0 for t in self.trucks.values()), 180,
            'the fleet')
        for truck in self.trucks.values():
            comms_handshake(lambda: self.executor.spin_once(timeout_sec=0.05), truck.send,
                            truck.reports, alive=lambda: not self.launch.poll())
        # The watch's own readers matched too (a pose taken, the events' writer heard), or the
        # first metres of a task would go uncounted and a collision unseen.
        self.spin_until(lambda: all(t._last is not None and t._events.publisher_count() > 0
                                    for t in self.trucks.values()), 60,
                        "every truck's pose and world events")

    def close(self) -> None:
        """Shut the probe and the fleet down."""
        import rclpy

        for truck in self.trucks.values():
            truck.node.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)
        self.launch.stop()
