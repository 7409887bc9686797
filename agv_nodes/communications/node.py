"""communications (ros2 run agv_nodes communications): comms/task in, comms/report out."""

import sys

from std_msgs.msg import String

from agv_nodes import qos
from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.core_node import CoreNode, spin_main


class CommunicationsNode(CoreNode):
    """CommunicationsCore on its ports, plus the text topics: its notes are the reports."""

    def __init__(self) -> None:
        super().__init__(CommunicationsCore)
        self.report_pub = self.create_publisher(String, 'comms/report', qos.EVENTS)
        self.create_subscription(String, 'comms/task', self._task, qos.EVENTS)

    def _task(self, msg: String) -> None:
        self.publish(self.core.on_task(msg.data, self.now_s()))

    def say(self, text: str, level: str) -> None:
        """Log a report and publish it on comms/report."""
        super().say(text, level)
        self.report_pub.publish(String(data=text))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes communications [--ros-args ...]."""
    return spin_main(CommunicationsNode, args)


if __name__ == '__main__':
    sys.exit(main())
