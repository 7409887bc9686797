"""Manual driving of the CONCIC-II from velocity commands, ROS-free (Rajagopalan 1991, App. F.4).

The thesis's keypad mode drove each wheel with the arrow keys, "equivalent to driving the
vehicle using a joy stick", to bring the truck where it is wanted and to check the drive chain
(App. F.4). Here the joystick is the ROS convention: a `geometry_msgs/Twist` on `cmd_vel`
(teleop_twist_keyboard drives it), its linear.x (m/s, + = forwards) and angular.z (rad/s, + =
left) turned into the two rim speeds by the truck's geometry, Eq. 5.13-5.14:

    V_L = V - psi' L / 2,   V_R = V + psi' L / 2      (L = steering.wheel_span)

V and psi' are first clipped to manual.max_speed and manual.max_yaw_rate; a pair whose faster
wheel would pass the drive's full-speed level (drive_safety.full_speed) is scaled down as a
whole, so the truck keeps the curve asked for and goes slower along it.

The supervisor (6.3.11's watchdog, for the command stream): a command older than
manual.timeout (sim time) stops the truck, motor off, until the next command arrives. A drive
fault (E-stop, the PAL's watchdog, ...) always wins: no command is taken while one is reported.
A command is refused, counted by reason and never acted on when the truck is not in manual mode
(`not_manual`), when a drive fault stands (`drive_fault`), when a component is not a finite
number (`not_finite`), or when it asks for motion a differential drive cannot make (linear.y,
linear.z, angular.x or angular.y not zero: `not_planar`).
"""

from __future__ import annotations

from collections import Counter
import math

from agv_nodes.route_following.settings import RouteParams
from agv_nodes.subsystem import Notes

REFUSALS = ('not_manual', 'drive_fault', 'not_finite', 'not_planar')


def wheel_speeds(speed: float, yaw_rate: float, span: float, top: float) -> tuple[float, float]:
    """Return the (left, right) rim speeds, m/s, for `speed` and `yaw_rate` (Eq. 5.13-5.14).

    A pair whose faster wheel passes `top` is scaled down as a whole (the curve is kept).
    """
    left, right = speed - yaw_rate * span / 2.0, speed + yaw_rate * span / 2.0
    fastest = max(abs(left), abs(right))
    if fastest > top:
        left, right = left * top / fastest, right * top / fastest
    return left, right


class ManualDrive:
    """See the module docstring; RouteCore hands it cmd_vel, the drive's fault and its loop."""

    def __init__(self, params: RouteParams, notes: Notes | None = None) -> None:
        self.p = params
        self.notes = notes or Notes()
        self.active = False  # in manual mode
        self.wheels = (0.0, 0.0)  # m/s asked of the rims
        self.motor_on = False
        self.refused: Counter[str] = Counter()  # commands refused, by reason (REFUSALS)
        self.taken = 0  # commands acted on
        self.clipped = 0  # of those, how many asked for more than the limits
        self.watchdog_stops = 0
        self.speed = self.yaw_rate = 0.0  # the command being driven, after the limits
        self._last: float | None = None  # sim time of the last command taken

    def enter(self, now: float) -> None:
        """Enter manual mode: at rest, motor off, until the first command."""
        self.active, self._last = True, None
        self._halt()
        self.notes.add(now, 'manual mode: driving from cmd_vel '
                            f'(stops after {self.p.manual.timeout:g} s without a command)')

    def leave(self, now: float) -> None:
        """Leave manual mode: motor off; later commands are refused."""
        if self.active:
            self.notes.add(now, f'manual mode left: {self.taken} command(s) taken, refused '
                                f'{dict(self.refused) or "none"}')
        self.active, self._last = False, None
        self._halt()

    def command(self, linear: tuple[float, float, float], angular: tuple[float, float, float],
                now: float, fault: str = 'none') -> str:
        """Take a Twist's linear and angular vectors; return 'taken' or the refusal's reason."""
        reason = ''
        if not self.active:
            reason = 'not_manual'
        elif fault != 'none':
            reason = 'drive_fault'
        elif not all(math.isfinite(v) for v in (*linear, *angular)):
            reason = 'not_finite'
        elif linear[1] or linear[2] or angular[0] or angular[1]:
            reason = 'not_planar'
        if reason:
            self.refused[reason] += 1
            if self.refused[reason] == 1:  # the first of each kind in words; all are counted
                self.notes.add(now, f'cmd_vel refused ({reason})', 'warn')
            return reason
        m = self.p.manual
        speed = max(-m.max_speed, min(m.max_speed, linear[0]))
        yaw_rate = max(-m.max_yaw_rate, min(m.max_yaw_rate, angular[2]))
        self.clipped += int(speed != linear[0] or yaw_rate != angular[2])
        self.taken += 1
        self.speed, self.yaw_rate, self._last = speed, yaw_rate, now
        self.wheels = wheel_speeds(speed, yaw_rate, self.p.steering.wheel_span,
                                   self.p.drive_safety.full_speed)
        self.motor_on = True
        return 'taken'

    def tick(self, now: float, fault: str = 'none') -> None:
        """Supervise: a drive fault, or a command older than the timeout, stops the truck."""
        if not self.active or not self.motor_on:
            return
        if fault != 'none':
            self.notes.add(now, f'manual mode: stopped, drive fault {fault}', 'warn')
            self._halt()
        elif self._last is not None and now - self._last > self.p.manual.timeout:
            self.watchdog_stops += 1
            self.notes.add(now, f'manual mode: cmd_vel silent for {now - self._last:.2f} s '
                                f'(timeout {self.p.manual.timeout:g} s): stopped', 'warn')
            self._halt()

    def _halt(self) -> None:
        self.wheels, self.motor_on, self.speed, self.yaw_rate = (0.0, 0.0), False, 0.0, 0.0
