"""traction: the only node that moves the truck (ros2 run agv_nodes traction).

Reads traction/command (executive), traction/link (navigation's direct link), hw/radio_stop and
hw/wheel_odometry; writes hw/traction/drive every loop and traction/status. All behaviour is in
`agv_nodes.traction.core`; see its docstring for the 1983 program and the trips.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.params import Parameters
from agv_nodes.traction.core import TractionCore, TractionParams


class TractionNode(CoreNode):
    """Parameters -> TractionCore -> ports."""

    def __init__(self) -> None:
        super().__init__('traction')
        p = Parameters(self)
        d = TractionParams()
        tp = TractionParams(
            loop_period=p.number('loop_period', d.loop_period, 'seconds per program loop '
                                 '(and per traction_drive record)', 0.001, 0.1),
            runout_wait=p.number('runout_wait', d.runout_wait, 'wait after a limited +-16 % '
                                 'step, s (thesis prose 0.200; listing formula 0.100)', 0.0, 1.0),
            field_wait=p.number('field_wait', d.field_wait, 'each FLIP wait and the start-up '
                                'field build-up, s (prose 0.100; listing formula 0.050)', 0.0,
                                1.0),
            field_duty=p.integer('field_duty', d.field_duty, 'field PWM duty, % (thesis 6.3: '
                                 '90; listing: 98)', 1, 100),
            arithmetic=p.choice('arithmetic', d.arithmetic, 'SUM arithmetic: the intended '
                                "saturating difference, or the listing's 8-bit wrap",
                                ('saturating', 'faithful_8bit')),
            emergency_stop=p.choice('emergency_stop', d.emergency_stop, 'on byte 2 = 00H: '
                                    'cut the armature at once, then plug-brake (immediate), or '
                                    'slew down 16 % per pass with the runout waits as the '
                                    'listing does (as_listed)', ('immediate', 'as_listed')),
            command_timeout=p.number('command_timeout', d.command_timeout, 'trip when the '
                                     "executive's command is older than this, s", 0.02, 5.0),
            stale_confirm=p.integer('stale_confirm', d.stale_confirm, 'wheel_odometry records '
                                    'that must arrive after a command or link before its age '
                                    'alone trips (0 = the timeout alone, as on the hardware)',
                                    0, 1000),
            link_reaction=p.choice('link_reaction', d.link_reaction, 'a traction_link with '
                                   'new contents: run a closed-loop pass at once (at_once), or '
                                   'wait for the next loop pass as the listing does (loop)',
                                   ('at_once', 'loop')),
            link_timeout=p.number('link_timeout', d.link_timeout, 'trip when the Position link '
                                  'being obeyed is older than this, s', 0.02, 5.0),
            stall_limit=p.number('stall_limit', d.stall_limit, 'trip when two loop passes are '
                                 'further apart than this, s', 0.02, 5.0),
            control=p.choice('control', d.control, 'speed control', ('open_loop_1983',
                                                                     'closed_loop')),
            kp=p.number('kp', d.kp, 'closed loop: % duty per m/s of speed error', 0.0, 1000.0),
            ki=p.number('ki', d.ki, 'closed loop: % duty per m of integrated error', 0.0,
                        1000.0),
            max_accel=p.number('max_accel', d.max_accel, 'closed loop: m/s^2 limit', 0.01,
                               5.0),
            max_jerk=p.number('max_jerk', d.max_jerk, 'closed loop: m/s^3 limit', 0.01, 50.0),
        )
        self.attach(TractionCore(tp), p)
        self._was_tripped: str | None = 'startup'

    def _tick(self) -> None:
        super()._tick()
        now = self.core.trip_cause if self.core.tripped else None
        if now != self._was_tripped:  # the trip relay's story, for the log files
            if now is None:
                self.get_logger().info('trip relay reset (00H then a demand)')
            else:
                self.get_logger().warn(f'trip relay open: {now}')
            self._was_tripped = now


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes traction [--ros-args ...]."""
    return spin_main(TractionNode, args)


if __name__ == '__main__':
    sys.exit(main())
