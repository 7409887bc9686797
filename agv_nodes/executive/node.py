"""executive: the Vehicle Executive (ros2 run agv_nodes executive).

Reads every sub-system's status record and comms/status; writes every command record and
comms/command; publishes /diagnostics (diagnostic_msgs/DiagnosticArray) once a second, with the
32-byte display of each sub-system (thesis 8.2.2). Behaviour: `agv_nodes.executive.core`.
"""

from __future__ import annotations

import sys
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock

from agv_nodes import qos
from agv_nodes.core_node import CoreNode, declare_executor, spin_main
from agv_nodes.executive.core import ExecutiveCore, ExecutiveParams
from agv_nodes.executive.diagnostics import HealthMonitor
from agv_nodes.params import Parameters
from agv_nodes.ros_ports import diagnostic_status
from agv_nodes.sent_time import SentTimeline


def parse_srm_map(entries: list[str]) -> dict[int, int]:
    """['1:15', '3:15'] -> {1: 15, 3: 15} (location: SRM angle in degrees, + = left)."""
    out = {}
    for entry in entries:
        location, _, angle = entry.partition(':')
        loc, ang = int(location), int(angle)
        if not (0 <= loc <= 31 and -45 <= ang <= 45):
            raise ValueError(entry)
        out[loc] = ang
    return out


class ExecutiveNode(CoreNode):
    """Parameters -> ExecutiveCore -> ports, plus /diagnostics."""

    def __init__(self) -> None:
        super().__init__('executive')
        p = Parameters(self)
        d = ExecutiveParams()
        srm = p.texts('srm_map', [], 'route map: location:angle pairs where the route leaves '
                      'the wire by an SRM (demo_1983: 1:15, 3:15)')
        try:
            srm_map = parse_srm_map(srm)
        except ValueError:
            p.fail('srm_map', srm, 'entries must be location:angle, 0-31 and -45..45')
        ep = ExecutiveParams(
            cruise_demand=p.integer('cruise_demand', d.cruise_demand, 'cruise, % armature duty '
                                    '(55 ~ 0.7 m/s, the practical top speed)', 6, 80),
            srm_demand=p.integer('srm_demand', d.srm_demand, 'wire changes, % duty (27 ~ '
                                 '0.3 m/s)', 6, 80),
            srm_map=srm_map,
            status_timeout=p.number('status_timeout', d.status_timeout, 'a status record older '
                                    'than this is a fault, s', 0.05, 10.0),
            stale_confirm=p.integer('stale_confirm', d.stale_confirm, 'records from the other '
                                    'sub-systems that must arrive after a status before its '
                                    'age alone makes it stale', 0, 1000),
            reject_limit=p.integer('reject_limit', d.reject_limit, 'rejected records per second '
                                   'tolerated', 0, 10000),
            route_limit=p.number('route_limit', d.route_limit, 'metres per step before the '
                                 'route is declared overrun', 1.0, 10000.0),
            positioning_limit=p.number('positioning_limit', d.positioning_limit, 'metres of '
                                       'positioning without reaching the stop marker', 0.5,
                                       100.0),
            load_timeout=p.integer('load_timeout', d.load_timeout, 'seconds per load transfer',
                                   1, 255),
            speed_request_path=p.choice('speed_request_path', d.speed_request_path, 'forward '
                                        "navigation's speed request (via_executive) or let the "
                                        'direct link carry it', ('direct_link',
                                                                 'via_executive')),
        )
        # Departure from the 1983 receiver-side monostables (thesis 6.3), default off: under
        # sim time `sent` ages a status from when it was sent, not from when this process got
        # round to it (agv_nodes.sent_time). Needs /clock and one wall clock for the graph.
        self.status_age = p.choice('status_age', 'arrival', 'age of a status record: from '
                                   'its arrival here (1983) or, under sim time, from when it '
                                   'was sent (a starved executive blames nobody)',
                                   ('arrival', 'sent'))
        self.executor_kind = declare_executor(p)
        # With the EventsExecutor every input, /clock included, is taken in arrival order
        # (core_node.ClockTimers), so a status is aged from its arrival in the queue, not from
        # when a starved executive took it: `sent` needs nothing more. With the
        # SingleThreadedExecutor it needs the DDS source timestamps (agv_nodes.sent_time).
        self.sent_stamps = self.status_age == 'sent' and self.executor_kind == 'single'
        self.timeline = SentTimeline()
        if self.sent_stamps and self.get_parameter('use_sim_time').value:
            # FIFO, unlike the ROS clock's keep-last-1 reader: time as the executive sees it
            # advances no faster than it takes its records (one sample per topic per turn).
            self.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK_READER)
        self.health = HealthMonitor(ep.status_timeout)
        self.attach(ExecutiveCore(ep), p)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        self.periodic(1.0, self._diagnostics)
        self._logged = 0

    def _on_clock(self, msg: Clock, info: dict[str, Any]) -> None:
        raised = self.timeline.clock(info.get('source_timestamp') or 0,
                                     msg.clock.sec + msg.clock.nanosec * 1e-9)
        for name, sent in raised:
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

    def _tick(self) -> None:
        super()._tick()
        log = self.core.log
        for _t, text in log[self._logged:]:
            self.get_logger().info(text)
        self._logged = len(log)

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
