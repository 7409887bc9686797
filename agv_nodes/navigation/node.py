"""navigation: PC6/1's navigating and positioning loops (ros2 run agv_nodes navigation).

Reads navigation/command, position_sensor/status and hw/wheel_odometry; writes
navigation/status, traction/link and position_sensor/command. Behaviour:
`agv_nodes.navigation.core`.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.navigation.core import NavigationCore, NavigationParams
from agv_nodes.params import Parameters


class NavigationNode(CoreNode):
    """Parameters -> NavigationCore -> ports."""

    def __init__(self) -> None:
        super().__init__('navigation')
        p = Parameters(self)
        d = NavigationParams()
        np_ = NavigationParams(
            variant=p.choice('variant', d.variant, "intended design, or the listing's quirks "
                             '(LOCN = 00H, second-stop-marker hazard)', ('intended', 'as_listed')),
            speed_request_path=p.choice(
                'speed_request_path', d.speed_request_path, "Position's speed request: the 1983 "
                'direct link, or in the status record via the executive (thesis 8.2.2)',
                ('direct_link', 'via_executive')),
            stopping=p.choice('stopping', d.stopping, 'stop sequence: 20 %/0 and friction '
                              '(1983), or a controlled stop on every view (thesis 8.5; needs '
                              'traction control:=closed_loop)', ('friction_1983', 'controlled')),
            period=p.number('period', d.period, 'loop period, s', 0.001, 0.1),
            landmark_wait=p.number('landmark_wait', d.landmark_wait, 'pause after reporting a '
                                   'landmark, s (PC6/1 WAIT: 0.052)', 0.0, 1.0),
            sensor_timeout=p.number('sensor_timeout', d.sensor_timeout, 'seconds without a '
                                    'sensor status before LOST', 0.01, 5.0),
            centre_lead=p.number('centre_lead', d.centre_lead, 'controlled stop: mm before '
                                 'alignment at which a view is first matched', -20.0, 20.0),
        )
        for name, value, reason in np_.check():
            p.fail(name, value, reason)
        self.attach(NavigationCore(np_), p)


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes navigation [--ros-args ...]."""
    return spin_main(NavigationNode, args)


if __name__ == '__main__':
    sys.exit(main())
