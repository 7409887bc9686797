"""vda5050_bridge (ros2 run agv_nodes vda5050_bridge): one truck driven by a VDA 5050 master.

MQTT on one side (agv_nodes.mqtt.MqttLink: the topics `<interface>/v2/<manufacturer>/
<serialNumber>/...` with the QoS and retain flags of agv_nodes.vda5050.topics, the last will
CONNECTIONBROKEN), the truck's radio path on the other: tasks as text on `comms/task`, its
communications node's lines back on `comms/report`. The logic is agv_nodes.vda5050.bridge; this
node only carries messages. paho delivers on its own thread, so received messages wait in a
queue that a wall-clock timer empties into the executor's thread. Before the first task the
bridge asks communications for `status` until it answers: what a writer sends before the
reader has matched it is lost (docs/tasks.md).

It also reads the truck's records the state needs (agv_nodes.vda5050.truck_records.RECORDS:
the cards read, the loads, traction's stops, the wheel counters) as one more reader, each judged
by its RecordReader (E2E counter and CRC where the record has them): a rejected record is
counted and never acted on.

/diagnostics `agv[/ns]/vda5050_bridge/link`: the MQTT link's counters, the messages taken and
the invalid ones (WARN while the last message was invalid, ERROR while the broker is gone), and
the records taken and rejected.
"""

from __future__ import annotations

from collections import deque
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import String, UInt8MultiArray

from agv_nodes import qos
from agv_nodes.mqtt.client import LastWill, MqttLink
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, refuse_unknown
from agv_nodes.records import codec
from agv_nodes.records.ports import RecordReader
from agv_nodes.ros_ports import ERROR, OK, WARN, diagnostic_status, record_bytes
from agv_nodes.settings import settings_class
from agv_nodes.vda5050.bridge import INBOUND, BridgeCore, Outbox
from agv_nodes.vda5050.codec import to_json
from agv_nodes.vda5050.connection import ConnectionState
from agv_nodes.vda5050.link_parameters import (
    broker_parameter,
    graph_parameter,
    security_parameters,
)
from agv_nodes.vda5050.topics import TOPICS, topic
from agv_nodes.vda5050.truck_factsheet import truck_factsheet
from agv_nodes.vda5050.truck_records import RECORDS

STATUS_EVERY = 0.5  # wall s between `status` queries until communications answers


@settings_class
class BridgeSettings:
    """One truck's link to a VDA 5050 master control (its parameters.yaml section)."""


class BridgeNode(Node):
    """See the module docstring."""

    def __init__(self) -> None:
        super().__init__('vda5050_bridge')
        s = declare(self, BridgeSettings)
        refuse_unknown(self)
        url = broker_parameter(self, s.mqtt_url)
        security = security_parameters(self, s, url)
        graph = graph_parameter(self, s.layout)
        self.settings = s
        self.core = BridgeCore(
            graph, s.manufacturer, s.serial_number,
            factsheet=lambda n: truck_factsheet(s.manufacturer, s.serial_number, n,
                                                state_interval=s.state_interval),
            state_interval=s.state_interval, map_id=s.layout)
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._task_pub = self.create_publisher(String, 'comms/task', qos.EVENTS)
        self.create_subscription(String, 'comms/report', self._report, qos.EVENTS)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        self._readers: dict[str, RecordReader] = {}
        for name in RECORDS:
            schema = codec()[name]
            self._readers[name] = RecordReader(schema, 'e2e' if schema.protected else 'none')
            self.create_subscription(UInt8MultiArray, schema.topic.lstrip('/'),
                                     lambda raw, name=name: self._record(name, raw),
                                     qos.reader_qos(schema), raw=True)
        self._inbox: deque[tuple[str, bytes]] = deque()
        self._connected: deque[bool] = deque()
        self._comms_answered = False
        self._pending: list[str] = []  # tasks held until communications has answered
        self._last_status = -float('inf')
        will = self.core.connection(ConnectionState.CONNECTIONBROKEN)
        self._topics = {name: topic(s.manufacturer, s.serial_number, name,
                                    interface=s.interface_name) for name in TOPICS}
        self.link = MqttLink(url, f'{s.manufacturer}_{s.serial_number}', LastWill(
            self._topics['connection'], to_json(will), qos=1, retain=True),
            reconnect_min_s=min(1.0, s.reconnect_max), reconnect_max_s=s.reconnect_max,
            security=security)
        self.link.on_connection(self._connected.append)
        for name in INBOUND:
            self.link.subscribe(self._topics[name], TOPICS[name].qos,
                                lambda _t, payload, name=name: self._inbox.append(
                                    (name, payload)))
        self.create_timer(s.poll_period, self._poll, clock=self._wall)
        self.create_timer(1.0, self._diagnostics, clock=self._wall)
        self.link.connect(timeout=None)
        self.get_logger().info(f'VDA 5050 bridge for {s.manufacturer}/{s.serial_number} on '
                               f'{url}, layout {s.layout}: {len(graph.nodes)} nodes')

    def _now(self) -> float:
        return time.monotonic()

    def _poll(self) -> None:
        """Take what paho queued, send pending tasks, keep the state interval."""
        now = self._now()
        while self._connected:
            if self._connected.popleft():
                self._send(self.core.reconnected(self.link.stats().last_gap_s, now))
            else:
                self.get_logger().warning(f'MQTT broker {self.link.url} lost: reconnecting; '
                                          'the truck goes on with the tasks it has')
        while self._inbox:
            name, payload = self._inbox.popleft()
            self._send(self.core.on_message(name, payload, now))
        if not self._comms_answered and now - self._last_status >= STATUS_EVERY:
            self._last_status = now
            self._task_pub.publish(String(data='status'))
        self._send(self.core.tick(now))

    def _report(self, msg: String) -> None:
        if msg.data.startswith('comms: status:'):
            self._comms_answered = True
        self._send(self.core.on_report(msg.data, self._now()))

    def _record(self, name: str, raw: bytes) -> None:
        fields = self._readers[name].accept(record_bytes(raw),
                                            self.get_clock().now().nanoseconds)
        if fields is not None:
            self._send(self.core.on_record(name, fields, self._now()))

    def _send(self, out: Outbox) -> None:
        self._pending += out.tasks
        if self._comms_answered:
            for text in self._pending:
                self._task_pub.publish(String(data=text))
            self._pending = []
        for name, message in out.messages:
            spec = TOPICS[name]
            self.link.publish(self._topics[name], to_json(message), spec.qos, spec.retain)

    def _diagnostics(self) -> None:
        stats = self.link.stats()
        counts = self.core.counts
        level, message = OK, 'connected'
        if not stats.connected:
            level, message = ERROR, 'broker not connected'
        elif self.core.last_invalid:
            level, message = WARN, f'invalid message: {self.core.last_invalid}'
        records = {'cards_read': self.core.records.reads,
                   'cards_unplaced': self.core.where.unplaced,
                   **{f'{name}_accepted': r.accepted for name, r in self._readers.items()},
                   **{f'{name}_rejected': r.rejected for name, r in self._readers.items()}}
        values = {k: str(v) for k, v in {**stats.as_dict(), **counts, **records}.items()}
        msg = DiagnosticArray(status=[diagnostic_status(self, f'{self.get_name()}/link', level,
                                                        message, self.get_name(), values)])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def close(self) -> None:
        """Say OFFLINE (6.14) and disconnect cleanly, so the broker drops the last will."""
        if self.link.connected:
            self._send(Outbox(messages=[('connection',
                                         self.core.connection(ConnectionState.OFFLINE))]))
        self.link.close(clean=True)

    def finish(self) -> None:
        """Close the MQTT link before the node's teardown (agv_nodes.node_process)."""
        self.close()


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes vda5050_bridge [--ros-args ...]."""
    return spin_main(BridgeNode, args)


if __name__ == '__main__':
    sys.exit(main())
