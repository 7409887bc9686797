"""The ultrasonic obstacle stop of the camera truck (Rajagopalan 1991, 6.3.11), ROS-free.

"The ultrasonic sensors are provided at the front of the vehicle. These devices are turned on
and off by software control. When an obstacle is detected, a software interrupt is generated and
the vehicle is brought to a halt using the motor off command which results in a fairly smooth
stop. The diagnostic software produces a message Obstacle detected. Once the obstacle is
removed, the vehicle accelerates to the original speed." (6.3.11; App. F: F3/F4 sonar on/off.)

Route following, the truck's computer, reads the sonar (hw/sonar, one reading a ping, m; +inf
no echo, -inf too near to time) and camera mode acts on it through its own motor-off path:
while `blocked` the steering_command asks nothing of the wheels with the motors off, and
route_status says `obstacle`. An echo nearer than `stop_range` (or -inf, or no number) blocks
at once; the way is clear after `clear_pings` readings in a row farther than `stop_range +
clear_margin`, and the truck sets off again on camera mode's set-off ramp to its cruise.

Safety first (modern, not in the thesis): a sonar heard once that then sends nothing for
`silent_time` is `silent`, a fault camera mode stops on (drive_fault sonar_silent) and the
executive fails the task on; it is latched until the next leg, as the safety supervisor's
software-detected faults are (drive_safety.py). A sonar never heard since start-up is not a
fault here (a graph whose world runs no sonar, the 1983 truck's); /diagnostics says so.
"""

from __future__ import annotations

import math

from agv_nodes.route_following.settings import ObstacleStopParams
from agv_nodes.subsystem import Notes


class ObstacleStop:
    """See the module docstring; RouteCore feeds it hw/sonar's readings and its loop's time."""

    def __init__(self, params: ObstacleStopParams, notes: Notes | None = None) -> None:
        self.p = params
        self.notes = notes or Notes()
        self.blocked = False  # an obstacle nearer than stop_range: the motors held off
        self.silent = False  # the sonar went silent (latched until clear())
        self.range = math.inf  # m, the last reading
        self.readings = 0
        self.stops = 0  # obstacle stops so far
        self._heard_at: float | None = None  # sim time of the last reading
        self._clear = 0  # clear readings in a row while blocked

    @property
    def holding(self) -> bool:
        """Return True while the sonar, switched on, holds the truck (an obstacle or silence)."""
        return self.p.enabled and (self.blocked or self.silent)

    def reading(self, value: float, now: float) -> None:
        """Take one sonar reading (m) at sim time `now`."""
        self._heard_at, self.range = now, value
        self.readings += 1
        if not self.p.enabled:
            self.blocked, self._clear = False, 0  # sonar off (F4): nothing is looked for
            return
        if not value >= self.p.stop_range:  # nearer, -inf (too near to time) or NaN
            self._clear = 0
            if not self.blocked:
                self.blocked = True
                self.stops += 1
                where = 'nearer than the sonar can time' if value == -math.inf \
                    else f'at {value:.2f} m'
                self.notes.add(now, f'Obstacle detected {where}: motor off', 'warn')
            return
        if not self.blocked:
            return
        self._clear = self._clear + 1 if value > self.p.stop_range + self.p.clear_margin else 0
        if self._clear >= self.p.clear_pings:
            self.blocked, self._clear = False, 0
            self.notes.add(now, 'obstacle removed: the way is clear '
                                + ('(no echo)' if value == math.inf else f'to {value:.2f} m')
                                + ', accelerating to the original speed')

    def check(self, now: float) -> None:
        """Find a sonar gone silent (run at the loop rate)."""
        if not self.p.enabled or self.silent or self._heard_at is None:
            return
        if now - self._heard_at > self.p.silent_time:
            self.silent = True
            self.notes.add(now, f'sonar silent for {now - self._heard_at:.2f} s '
                                f'(more than {self.p.silent_time:g} s): motor off', 'error')

    def clear(self) -> None:
        """Forget a silent sonar at a new leg (check() finds it again if it is still silent)."""
        self.silent = False

    def health(self) -> tuple[int, str]:
        """Return (level, message) for /diagnostics: 0 clear, 1 obstacle or unheard, 2 silent."""
        if not self.p.enabled:
            return 0, 'sonar off'
        if self.silent:
            return 2, 'sonar silent: stopped'
        if self.blocked:
            return 1, f'Obstacle detected ({self.range:.2f} m): stopped'
        if self._heard_at is None:
            return 1, 'sonar not heard yet'
        return 0, ''
