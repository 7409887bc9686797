"""Navigation settings: every parameter of the navigation node, its default and its meaning."""

from __future__ import annotations

from dataclasses import dataclass

from agv_nodes.settings import setting


@dataclass
class NavigationParams:
    """PC6/1's navigating and positioning loops (thesis App. B.1) and the controlled stop."""

    variant: str = setting('intended', "intended design, or the listing's quirks (LOCN = 00H, "
                           'second-stop-marker hazard)', choices=('intended', 'as_listed'))
    speed_request_path: str = setting('direct_link', "Position's speed request: the 1983 "
                                      'direct link, or in the status record via the executive '
                                      '(thesis 8.2.2)',
                                      choices=('direct_link', 'via_executive'))
    # The controlled stop ends within +-3 mm of the centre where friction_1983 rolls +34..+55
    # mm past it (bench/stop_bench.py).
    stopping: str = setting('controlled', 'stop sequence: a controlled stop on every view '
                            '(thesis 8.5; needs traction control: closed_loop), or 20 %/0 and '
                            'friction (friction_1983, as built)',
                            choices=('controlled', 'friction_1983'))
    period: float = setting(0.010, 'loop period (CHK) and controlled-stop update, s', lo=0.001,
                            hi=0.1)
    status_period: float = setting(0.050, 'seconds between navigation_status heartbeats',
                                   lo=0.01, hi=1.0)
    link_period: float = setting(0.020, 'seconds between traction_link records (one goes out '
                                 'at once on a change)', lo=0.005, hi=1.0)
    command_period: float = setting(0.050, 'seconds between position_sensor_command records',
                                    lo=0.01, hi=1.0)
    landmark_wait: float = setting(0.052, 'pause after reporting a landmark, s (PC6/1 WAIT: '
                                   '0.052)', lo=0.0, hi=1.0)
    # Five of the position sensor's 20 ms heartbeats: a silent sensor has the link ask for
    # speed 0 within ~110 ms (with the 10 ms loop), inside the 200 ms the fault tests allow
    # after any node goes silent, while one or two late statuses do not call it lost.
    sensor_timeout: float = setting(0.100, 'seconds without a position sensor status before '
                                    'LOST', lo=0.01, hi=5.0)
    centre_lead: float = setting(5.0, 'controlled stop: mm before alignment at which a view is '
                                 'first matched', lo=-20.0, hi=20.0)
    reverse_speed: int = setting(12, 'controlled stop: % duty of the slow reverse back onto '
                                 'the centre after an overshoot (thesis 8.5 F5)', lo=1, hi=80)
    settle_time: float = setting(0.3, 'controlled stop: seconds at rest before it reports 0BH',
                                 lo=0.0, hi=5.0)
