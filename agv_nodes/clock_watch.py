"""ClockWatch: a node's word, on the wall clock, that sim time has stopped; and its /clock row.

Besides the loss it says, in a `<node>/clock` row, what the node's /clock reader refused or found
(core_node.ClockTimers): samples from a foreign writer (WARN while they come) and jumps of the
genuine writer's clock (ERROR: `clock jumped` with the times from and to).
"""

import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType

from agv_nodes import qos
from agv_nodes.records import codec
from agv_nodes.records.ports import inputs_report
from agv_nodes.ros_ports import diagnostic_status


class ClockWatch:
    """Says on /diagnostics, on the wall clock, that sim time has stopped (the world is gone).

    Under sim time every timer of a node, its /diagnostics included, runs on the world's
    /clock: with the world killed, time stands still and no node would ever say so. A steady
    timer notices that the node's time has not moved for `LOST_AFTER` s of wall time and
    publishes its inputs row as ERROR: "clock lost", the hardware (world) inputs lost and the
    other inputs silent since. The world's pacing waits up to 1.5 s (lag_patience) for a slow
    node, so a shorter silence is not yet a loss; a paused world reads the same. A node that
    was itself frozen (SIGSTOP) or starved finds a long gap between its own checks, and starts
    counting afresh. Once /clock moves again, the node's own sim-time row says OK again.
    """

    LOST_AFTER = 2.0  # s of wall time

    def __init__(self, node: Any, period: float = 0.5) -> None:
        self._node = node
        self._seen = 0.0  # the node's sim time at the last check
        self._since = self._checked = time.monotonic()
        self._accepted: dict[str, int] = {}
        self._rejected_before = 0
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        node.create_timer(period, self.check, clock=RosClock(clock_type=ClockType.STEADY_TIME))

    def check(self) -> None:
        """Publish the loss if sim time has stood still for LOST_AFTER s of wall time."""
        self._clock_row()
        node, readers = self._node, self._node.readers
        now, wall = node.ros_now_s(), time.monotonic()
        stalled = wall - self._checked > self.LOST_AFTER  # this process was frozen or starved
        self._checked = wall
        if now != self._seen or stalled:  # (its /clock samples may still wait in its queue)
            self._seen, self._since = now, wall
            self._accepted = {name: r.accepted for name, r in readers.items()}
            return
        if now <= 0 or wall - self._since < self.LOST_AFTER:
            return  # the world has not started, or is only slow
        silent = [n for n, r in sorted(readers.items()) if r.accepted == self._accepted.get(n)]
        hardware = [n for n in silent if codec()[n].writer == 'world']
        others = [n for n in silent if n not in hardware]
        message = (f'clock lost: sim time stopped at {now:.3f} s, no /clock for '
                   f'{wall - self._since:.1f} s of wall time (world gone or paused); '
                   f'hardware inputs lost: {", ".join(hardware) or "none"}; silent since: '
                   f'{", ".join(others) or "none"}')
        values = inputs_report(readers)[2]  # the counts, as the sim-time row has them
        values.update({'sim time (s)': f'{now:.3f}', 'wall s without /clock':
                       f'{wall - self._since:.1f}', 'silent inputs': ', '.join(silent) or 'none'})
        name = node.get_name()
        msg = DiagnosticArray(status=[diagnostic_status(node, f'{name}/inputs', 2, message,
                                                       name, values)])
        msg.header.stamp = node.get_clock().now().to_msg()
        self._pub.publish(msg)

    def _clock_row(self) -> None:
        """Publish `<node>/clock` once the reader has rejected a sample or seen a jump."""
        timers = getattr(self._node, '_clock_timers', None)
        if timers is None or not (timers.rejects or timers.rule.jumps):
            return
        rejected = sum(timers.rejects.values())
        reasons = ', '.join(f'{k}={v}' for k, v in sorted(timers.rejects.items()))
        jumps = timers.rule.jumps
        if jumps:  # a fault: it stays said
            level = 2
            message = (f'{jumps[-1].text()} (/clock from {timers.writer}; {len(jumps)} '
                       f'jump{"s" if len(jumps) > 1 else ""} in all)')
        elif rejected > self._rejected_before:
            level, message = 1, f'/clock from a foreign writer rejected: {timers.last_rejection}'
        else:
            level, message = 0, f'/clock from {timers.writer} only ({rejected} rejected in all)'
        self._rejected_before = rejected
        values = {'clock writer': timers.identity, 'accepted': str(timers.accepted),
                  'rejected': str(rejected), 'rejects by reason': reasons or 'none',
                  'last rejection': timers.last_rejection or 'none',
                  'jumps': '; '.join(j.text() for j in jumps[-5:]) or 'none',
                  'jump limit (s)': f'{timers.rule.limit_ns * 1e-9:g}',
                  'writer time - node time (s)': f'{timers.rule.offset_ns * 1e-9:.3f}'}
        node = self._node
        name = node.get_name()
        msg = DiagnosticArray(status=[diagnostic_status(node, f'{name}/clock', level, message,
                                                       name, values)])
        msg.header.stamp = node.get_clock().now().to_msg()
        self._pub.publish(msg)
