"""executive (ros2 run agv_nodes executive); also /diagnostics, the 32-byte display (8.2.2)."""

import sys
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock

from agv_nodes import qos
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.diagnostics import HealthMonitor
from agv_nodes.ros_ports import diagnostic_status
from agv_nodes.sent_time import SentTimeline


class ExecutiveNode(CoreNode):
    """ExecutiveCore on its ports, plus /diagnostics and the age of statuses.

    `status_age: sent` (a departure from thesis 6.3's receiver-side monostables) ages a status from
    its send. The EventsExecutor takes /clock in arrival order with the rest (core_node
    ClockTimers), so that needs nothing more; the SingleThreadedExecutor needs DDS source
    timestamps (agv_nodes.sent_time) and a FIFO /clock reader.
    """

    @property
    def sent_stamps(self) -> bool:
        """Readers keep each record's DDS source timestamp (status_age sent, `single`)."""
        return self.core.p.status_age == 'sent' and self.node_settings.executor == 'single'

    def __init__(self) -> None:
        self.timeline = SentTimeline()
        super().__init__(ExecutiveCore)
        if self.sent_stamps and self.get_parameter('use_sim_time').value:
            self.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK_READER)
        self.health = HealthMonitor(self.core.p.status_timeout)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        self.periodic(1.0, self._diagnostics)

    def _on_clock(self, msg: Clock, info: dict[str, Any]) -> None:
        sim = msg.clock.sec + msg.clock.nanosec * 1e-9
        for name, sent in self.timeline.clock(info.get('source_timestamp') or 0, sim):
            self.core.sent_later(name, sent)

    def now_s(self) -> float:
        """Sim time as far as the executive has taken its inputs (status_age `sent`)."""
        return self.timeline.now() if self.timeline else super().now_s()

    def _on_record(self, name: str):
        if not self.sent_stamps:
            return super()._on_record(name)

        def callback(fields: dict[str, Any]) -> None:
            sent = self.timeline.record(name, self.readers[name].sent_ns) if self.timeline \
                else None
            self.publish(self.core.on_record(name, fields, self.now_s(), sent))
        return callback

    def _diagnostics(self) -> None:
        # The readers stamp arrivals on the ROS clock: the display ages them on it too.
        rows = self.health.update(super().now_s(), self.readers, self.writers, self.core)
        msg = DiagnosticArray(status=[
            diagnostic_status(self, row.name, row.level, row.message, row.name, row.values)
            for row in rows])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes executive [--ros-args ...]."""
    return spin_main(ExecutiveNode, args)


if __name__ == '__main__':
    sys.exit(main())
