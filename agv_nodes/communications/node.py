"""communications: tasks in on comms/task, reports out on comms/report (ros2 run agv_nodes
communications).

comms/task and comms/report are std_msgs/String; the task language is in
`agv_nodes.communications.core` and docs/tasks.md. Tasks go to the executive as comms/status
records; its comms/command records come back as reports.
"""

from __future__ import annotations

import sys

from std_msgs.msg import String

from agv_nodes import qos
from agv_nodes.communications.core import CommsParams, CommunicationsCore
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.params import Parameters


class CommunicationsNode(CoreNode):
    """Parameters -> CommunicationsCore -> ports, plus the text topics."""

    def __init__(self) -> None:
        super().__init__('communications')
        p = Parameters(self)
        locations = p.numbers('locations', [0.0, 1.0, 2.0, 3.0], 'location marker '
                              'identities on the floor')
        if not all(v.is_integer() and 0 <= v <= 31 for v in locations):
            p.fail('locations', locations, 'identities must be integers 0-31')
        self.attach(CommunicationsCore(CommsParams(locations=tuple(int(v) for v in locations))),
                    p)
        self.report_pub = self.create_publisher(String, 'comms/report', qos.EVENTS)
        self.create_subscription(String, 'comms/task', self._task, qos.EVENTS)

    def _task(self, msg: String) -> None:
        self.publish(self.core.on_task(msg.data, self.now_s()))
        self._reports()

    def _on_record(self, name: str):
        inner = super()._on_record(name)

        def callback(fields):
            inner(fields)
            self._reports()
        return callback

    def _reports(self) -> None:
        for line in self.core.reports:
            self.get_logger().info(line)
            self.report_pub.publish(String(data=line))
        self.core.reports.clear()


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes communications [--ros-args ...]."""
    return spin_main(CommunicationsNode, args)


if __name__ == '__main__':
    sys.exit(main())
