"""dispatcher (ros2 run agv_nodes dispatcher): the fleet's central computer as a ROS node.

The node is the VDA 5050 master of the trucks named in `trucks`: agv_nodes.fleet.mqtt_master
(the dispatcher on an MQTT link) does the work; this node only carries text in and out and
keeps the time. Transport orders arrive as text on `fleet/transport` (std_msgs/String, syntax
mqtt_master.TRANSPORT_SYNTAX, e.g. `W0 to W2` or `job7: W0 to W2`); each answer and each step
of a transport's way goes out as one line on `fleet/report`:

    t1: accepted: W0 to W2
    t1: queued: no idle truck can take it yet
    t1: assigned to agv1
    t1: done (agv1)            or   t1: failed (agv1): <the truck's words>
    rejected 'W9 to W2': unknown station 'W9' (stations: W0, W1, W2, W3)

`status` is a query: the answer is one line, `status: 0 queued, 1 assigned, 3 done, ...`.

The dispatcher steps every `period` s on the node's clock (sim time with use_sim_time), so a
simulated fleet is directed at the pace of its simulation. /diagnostics `agv[/ns]/dispatcher/
fleet`, once a wall-clock second (so a stopped clock or a lost broker still shows): the queue,
the assignments, done, failed, deadlocks, the rejected transports and truck messages, the
messages sent and the MQTT link's counters; ERROR while the broker is gone, WARN while a
deadlock or a conflict stands, a truck is off the broker, or the last truck message was
rejected.
"""

from __future__ import annotations

from collections import deque
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import String

from agv_nodes import qos
from agv_nodes.fleet.dispatcher import Dispatcher
from agv_nodes.fleet.mqtt_master import MqttMaster
from agv_nodes.fleet.settings import DispatcherSettings, truck_map
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.ros_ports import ERROR, OK, WARN, diagnostic_status
from agv_nodes.settings import SettingError
from agv_nodes.vda5050.link_parameters import (
    broker_parameter,
    graph_parameter,
    security_parameters,
)

# A query, not a transport: answered with one line of counts and changing nothing, so a program
# that starts with the node asks it until answered, which proves both directions of the topics
# (a writer's first messages before the reader matched it back are lost).
STATUS = 'status'
STEPS_KEPT = 10_000  # dispatcher steps whose time /diagnostics summarises (~17 min at 0.1 s)
RECONNECT_MAX = 10.0  # wall s: the longest wait between attempts to reach a lost broker


class DispatcherNode(Node):
    """See the module docstring."""

    def __init__(self) -> None:
        super().__init__('dispatcher')
        s = declare(self, DispatcherSettings)
        refuse_unknown(self)
        url = broker_parameter(self, s.mqtt_url)
        graph = graph_parameter(self, s.layout)
        stops = {n.id for n in graph.nodes.values() if n.stoppable}
        try:
            positions, parking = (truck_map(name, getattr(s, name), s.trucks, stops)
                                  for name in ('positions', 'parking'))
        except SettingError as exc:
            raise parameter_error(self, exc.name, exc.value, exc.reason) from None
        self.settings = s
        dispatcher = Dispatcher(graph, list(s.trucks), manufacturer=s.manufacturer,
                                parking=parking, positions=positions,
                                reroute_after=s.reroute_after)
        self.link = MqttLink(url, f'{s.manufacturer}_dispatcher', reconnect_min_s=1.0,
                             reconnect_max_s=RECONNECT_MAX,
                             security=security_parameters(self, s, url))
        self.master = MqttMaster(dispatcher, self.link)
        self._report_pub = self.create_publisher(String, 'fleet/report', qos.EVENTS)
        self.create_subscription(String, 'fleet/transport', self._transport, qos.EVENTS)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        self._was_connected = False
        self._decisions: deque[float] = deque(maxlen=STEPS_KEPT)  # wall s of each step
        self._deadlocks: list[list[str]] = []
        self.create_timer(s.period, self._step)  # the node's clock: sim time with use_sim_time
        self.create_timer(1.0, self._diagnostics, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.link.connect(timeout=None)  # in the background: the node runs without a broker
        self.get_logger().info(f'dispatcher for {", ".join(s.trucks)} of {s.manufacturer} on '
                               f'{url}, layout {s.layout}: stations '
                               f'{", ".join(self.master.stations)}')

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _report(self, line: str) -> None:
        self._report_pub.publish(String(data=line))
        self.get_logger().info(line)

    def _transport(self, msg: String) -> None:
        if msg.data.strip().lower() == STATUS:
            c = self.master.counts()
            self._report(f'{STATUS}: {c["queue"]} queued, {c["assignments"]} assigned, '
                         f'{c["done"]} done, {c["failed"]} failed; trucks heard '
                         f'{c["trucks heard"]}, online {c["trucks online"]}')
            return
        self._report(self.master.submit(msg.data))

    def _step(self) -> None:
        connected = self.link.connected
        if connected != self._was_connected:
            self._was_connected = connected
            if connected:
                self.get_logger().info(f'MQTT broker {self.link.url} connected')
            else:
                self.get_logger().warning(f'MQTT broker {self.link.url} lost: no orders are '
                                          'sent until it is back')
        t0 = time.perf_counter()
        self.master.step(self._now())
        self._decisions.append(time.perf_counter() - t0)
        for line in self.master.progress():
            self._report(line)
        deadlocks = self.master.dispatcher.deadlocks
        if deadlocks != self._deadlocks:
            self._deadlocks = [list(c) for c in deadlocks]
            if deadlocks:  # on a one-way loop nothing can route around it: say so, once
                self.get_logger().error(f'deadlock: {deadlocks} wait for each other')

    def _diagnostics(self) -> None:
        stats = self.link.stats()
        counts = self.master.counts()
        offline = [t for t in self.master.trucks if not self.master.online(t)]
        d = self.master.dispatcher
        level, message = OK, 'connected'
        if not stats.connected:
            level, message = ERROR, 'broker not connected'
        elif d.deadlocks:
            level, message = WARN, f'deadlock: {d.deadlocks}'
        elif d.conflicts:  # a truck found in a block another holds: traffic control failed
            level, message = WARN, f'conflicts: {d.conflicts}'
        elif offline:
            level, message = WARN, f'off the broker: {", ".join(offline)}'
        elif self.master.rejecting:
            level, message = WARN, f'rejected: {self.master.last_rejection}'
        values = {k: str(v) for k, v in {**counts, **stats.as_dict()}.items()}
        values['last rejection'] = self.master.last_rejection
        if self._decisions:  # a step: take the states, assign, grant, send (the last ones)
            ms = sorted(1000.0 * t for t in self._decisions)
            values.update({'steps': str(len(ms)), 'step median ms': f'{ms[len(ms) // 2]:.3f}',
                           'step p99 ms': f'{ms[int(0.99 * (len(ms) - 1))]:.3f}',
                           'step max ms': f'{ms[-1]:.3f}'})
        msg = DiagnosticArray(status=[diagnostic_status(self, f'{self.get_name()}/fleet', level,
                                                        message, self.get_name(), values)])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def finish(self) -> None:
        """Close the MQTT link before the node's teardown (agv_nodes.node_process)."""
        self.link.close(clean=True)


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes dispatcher [--ros-args ...]."""
    return spin_main(DispatcherNode, args)


if __name__ == '__main__':
    sys.exit(main())
