"""The stop switches on their topics: hw/radio_stop and hw/bumper (std_msgs/Bool, true = stop).

Each is taken from its named writer only (records.writer_check.SwitchInput: a foreign `true`
still stops, a foreign `false` never releases), the writer by default the one settings.py's
SWITCH_WRITERS names, or another the node's `record_writers` names (`radio_stop=<node>` or
`radio_stop=gid:<hex>`). Traction and the world read them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.serialization import deserialize_message
from std_msgs.msg import Bool

from agv_nodes import qos
from agv_nodes.rclpy_internals import writer_identity_unavailable, writer_tagged_subscription
from agv_nodes.records.ports import SwitchInput, WriterCheck
from agv_nodes.ros_ports import graph_writers, node_time, writer_name
from agv_nodes.settings import SWITCH_WRITERS

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
            node.create_subscription(Bool, topic, lambda msg: self._unchecked(msg.data), profile)

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
