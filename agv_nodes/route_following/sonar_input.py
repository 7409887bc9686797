"""hw/sonar (sensor_msgs/Range) into route following, from its named writer (the world).

The camera truck's front sonar (agv_nodes/world/sonar.py, or a driver of the real one) is taken
as the cameras' frames are (agv_nodes/stop_switches.py, FrameSubscription): the named writer's
readings are acted on, any other's refused, counted and named in /diagnostics. A reading that is
no ultrasound range is refused too (`not_ultrasound`), so a misrouted laser or infrared range
cannot stand in for the sonar; its silence then stops the truck as any silence does.
"""

from __future__ import annotations

from collections.abc import Callable

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Range

from agv_nodes import qos
from agv_nodes.rclpy_internals import writer_identity_unavailable, writer_tagged_subscription
from agv_nodes.records.ports import CheckedInput, WriterCheck
from agv_nodes.ros_ports import graph_writers, node_time, writer_name

TOPIC = 'hw/sonar'
WRITER = 'world'


class SonarSubscription(CheckedInput):
    """The sonar's readings: `callback(range_m)` for each of its named writer's."""

    def __init__(self, node: Node, callback: Callable[[float], None]) -> None:
        super().__init__('sonar', WriterCheck(writer_name(node, 'sonar', WRITER),
                                              lambda: graph_writers(node, TOPIC)))
        self._callback = callback
        self._now_ns = node_time(node)
        self._tagged = writer_tagged_subscription(node, Range, TOPIC, qos.STREAM_READER,
                                                  self._on_sample)
        if self._tagged is None:
            node.create_subscription(Range, TOPIC, self._act, qos.STREAM_READER)

    def identity(self) -> str:
        """Say whose readings these are (its /diagnostics `writer` value)."""
        if self._tagged is None:
            return f'not checked: {writer_identity_unavailable()}'
        return super().identity()

    def _act(self, msg: Range) -> None:
        if msg.radiation_type != Range.ULTRASOUND:
            self._refused('not_ultrasound', b'', f'sonar: radiation_type {msg.radiation_type} '
                          'is no ultrasound range')
            return
        self._callback(float(msg.range))

    def _on_sample(self, raw: bytes, gid: bytes | None, _stamp: int) -> None:
        if gid is None:  # the message info is not laid out as in Jazzy: no GID
            self._act(deserialize_message(raw, Range))
            return
        for sample in self.take(raw, gid, self._now_ns()):
            self._act(deserialize_message(sample, Range))
