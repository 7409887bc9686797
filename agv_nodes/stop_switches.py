"""The inputs that are no records but can stop or move a truck, each from its named writer.

The stop switches hw/radio_stop and hw/bumper (std_msgs/Bool, true = stop; traction and the world
read them): records.writer_check.SwitchInput, a foreign `true` still stops, a foreign `false`
never releases. The cameras' frames hw/camera/front and /rear (route following steers the
CONCIC-II by them): records.writer_check.CheckedInput, a foreign frame is refused. The writer is
by default the one settings.py's SWITCH_WRITERS or FRAME_WRITERS names, or another the node's
`record_writers` names (`radio_stop=<node>`, `camera_front=gid:<hex>`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from std_msgs.msg import Bool

from agv_nodes import qos
from agv_nodes.rclpy_internals import writer_identity_unavailable, writer_tagged_subscription
from agv_nodes.records.ports import CheckedInput, SwitchInput, WriterCheck
from agv_nodes.ros_ports import graph_writers, node_time, writer_name
from agv_nodes.settings import FRAME_WRITERS, SWITCH_WRITERS

TOPICS = {'radio_stop': ('hw/radio_stop', qos.RECORD_READER), 'bumper': ('hw/bumper', qos.LATCHED)}


class SwitchSubscription(SwitchInput):
    """One stop switch: `callback(on)` for each value to act on (see SwitchInput.take).

    Taken with its writer's GID as the record readers take theirs; where that cannot be had
    the check is off (said in the `writer` value) and every value is acted on.
    """

    def __init__(self, node: Node, name: str, callback: Callable[[bool], None]) -> None:
        topic, profile = TOPICS[name]
        super().__init__(name, WriterCheck(writer_name(node, name, SWITCH_WRITERS[name]),
                                           lambda: graph_writers(node, topic)))
        self._callback = callback
        self._now_ns = node_time(node)
        self._tagged = writer_tagged_subscription(node, Bool, topic, profile, self._on_sample)
        if self._tagged is None:
            node.create_subscription(Bool, topic, self._on_msg, profile)

    def _on_msg(self, msg: Bool) -> None:
        self._unchecked(msg.data)

    def identity(self) -> str:
        """Say whose switch this is (its /diagnostics `writer` value)."""
        if self._tagged is None:
            return f'not checked: {writer_identity_unavailable()}'
        return super().identity()

    def _unchecked(self, on: bool) -> None:
        self.accepted += 1
        self.value, self.stamp_ns = bool(on), self._now_ns()
        self._callback(bool(on))

    def _on_sample(self, raw: bytes, gid: bytes | None, _stamp: int) -> None:
        on = bool(deserialize_message(raw, Bool).data)
        if gid is None:  # the message info is not laid out as in Jazzy: no GID
            self._unchecked(on)
            return
        for value in self.take(on, gid, self._now_ns()):
            self._callback(value)


class FrameSubscription(CheckedInput):
    """One camera's frames (sensor_msgs/Image): `callback(msg)` for each of its named writer."""

    def __init__(self, node: Node, camera: str, profile: Any,
                 callback: Callable[[Any], None]) -> None:
        from sensor_msgs.msg import Image

        name, topic = f'camera_{camera}', f'hw/camera/{camera}'
        super().__init__(name, WriterCheck(writer_name(node, name, FRAME_WRITERS[name]),
                                           lambda: graph_writers(node, topic)))
        self._type, self._callback = Image, callback
        self._now_ns = node_time(node)
        self._tagged = writer_tagged_subscription(node, Image, topic, profile, self._on_sample)
        if self._tagged is None:
            node.create_subscription(Image, topic, callback, profile)

    def identity(self) -> str:
        """Say whose frames these are (its /diagnostics `writer` value)."""
        if self._tagged is None:
            return f'not checked: {writer_identity_unavailable()}'
        return super().identity()

    def _on_sample(self, raw: bytes, gid: bytes | None, _stamp: int) -> None:
        if gid is None:  # the message info is not laid out as in Jazzy: no GID
            self._callback(deserialize_message(raw, self._type))
            return
        for sample in self.take(raw, gid, self._now_ns()):
            self._callback(deserialize_message(sample, self._type))


def switch_inputs(node: Any) -> dict[str, SwitchSubscription]:
    """Subscribe the switches `node.core` reads (on_radio_stop, on_bumper), by name."""
    core = node.core
    out = {}
    if hasattr(core, 'on_radio_stop'):
        out['radio_stop'] = SwitchSubscription(
            node, 'radio_stop', lambda on: core.on_radio_stop(on, node.now_s()))
    if hasattr(core, 'on_bumper'):  # the world's (or the truck's) bumper switch
        out['bumper'] = SwitchSubscription(
            node, 'bumper', lambda on: core.on_bumper(on, node.now_s()))
    return out
