"""communications (ros2 run agv_nodes communications): comms/task in, comms/report out.

comms/task is read with each message's writer and sequence number (a WriterTaggedSubscription
through librcl; rclpy's message info has no writer), so that messages a writer sent and
communications never read are counted as lost: Fast DDS 2.14 raises no "message lost" event when
a reader's history overflows (docs/tasks.md, "Limits"). The task counts go on /diagnostics as
`agv[/ns]/communications/tasks` once a second.
"""

import sys
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from agv_nodes import qos
from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.rclpy_internals import WriterTaggedSubscription, writer_identity_unavailable
from agv_nodes.ros_ports import diagnostic_status

TOPIC = 'comms/task'


class SequencedSubscription(WriterTaggedSubscription):
    """Its samples come as (raw, writer GID, source stamp, the writer's sequence number)."""

    def take(self) -> tuple[bytes, bytes | None, int, int] | None:
        """Take one queued message, with its publication sequence number."""
        taken = super().take()
        if taken is None:
            return None
        return (*taken, self._info.publication_sequence_number)


class CommunicationsNode(CoreNode):
    """CommunicationsCore on its ports, plus the text topics: its notes are the reports."""

    def __init__(self) -> None:
        super().__init__(CommunicationsCore)
        self.report_pub = self.create_publisher(String, 'comms/report', qos.TASKS)
        self.task_sub: Any = None
        if writer_identity_unavailable():  # said once on stderr; losses then go uncounted
            self.task_sub = self.create_subscription(String, TOPIC, self._task, qos.TASKS)
        else:
            self.task_sub = SequencedSubscription(self, String, TOPIC, qos.TASKS,
                                                  self._sequenced_task)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        self._refused_before = 0
        self.periodic(1.0, self._diagnostics)

    def _task(self, msg: String) -> None:
        self.publish(self.core.on_task(msg.data, self.now_s()))

    def _sequenced_task(self, raw: bytes, gid: bytes | None, _stamp: int, sequence: int) -> None:
        text = deserialize_message(raw, String).data
        # without the writer's GID, sequences of two writers would mix: count no losses then
        self.publish(self.core.on_task(text, self.now_s(), gid,
                                       sequence if gid is not None else None))

    def _diagnostics(self) -> None:
        level, message, values = self.core.task_report(self._refused_before)
        self._refused_before = self.core.refused_or_lost()
        name = self.get_name()
        msg = DiagnosticArray(status=[diagnostic_status(self, f'{name}/tasks', level, message,
                                                        name, values)])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def say(self, text: str, level: str) -> None:
        """Log a report and publish it on comms/report."""
        super().say(text, level)
        self.report_pub.publish(String(data=text))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes communications [--ros-args -p ...]."""
    return spin_main(CommunicationsNode, args)


if __name__ == '__main__':
    sys.exit(main())
