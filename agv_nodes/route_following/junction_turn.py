"""Taking a junction in camera mode (Rajagopalan 1991, App. F.6-F.7): approach, wait, spin.

Once the chosen branch shows at the leading window's edge column, the vehicle slows ("decelerate
gradually") and stops with its axle centre over the crossing, judged by wheel odometry
(App. F.6). A scripted wait (App. F.7) holds it there, state `waiting`; a straight choice
with a wait stops there too (placed by whichever branch shows), and without one does not stop
at all. It then spins in place a quarter turn toward the branch (the thesis does not describe
the turn; a spin about the axle centre is assumed) and comes to rest, or, straight on, sets off
again. Left and right are those of the direction of travel: a left branch turns the direction
of travel counter-clockwise, and so the body too, going forwards or backwards.

The manoeuvre runs at the loop rate (the frames come at only ~20 Hz); the frames place the
crossing and steer the approach.
"""

import math

from agv_nodes.odometry import Odometer
from agv_nodes.route_following.camera_law import CameraLaw
from agv_nodes.route_following.settings import RouteParams

AT_REST = 0.005  # m/s of each wheel under which the vehicle counts as at rest


class JunctionTurn:
    """One junction's manoeuvre; `phase` '' when there is none."""

    def __init__(self, params: RouteParams) -> None:
        self.p = params
        self.phase = ''  # '' | approach (to the crossing) | wait | spin | settle (to rest)
        self.way = 'straight'  # the branch taken: left | right | straight
        self.side = 'left'  # the branch whose edge places the crossing
        self.wait = 0.0  # s held over the crossing
        self.direction = 1
        self.wheels = (0.0, 0.0)  # m/s asked of the rims
        self._from = (0.0, 0.0)  # each wheel's travel when the phase began, m
        self._crossing = 0.0  # m of travel from the phase's start to the crossing
        self._began: float | None = None  # sim time of the manoeuvre's first pass
        self._wait_until = 0.0

    def begin(self, way: str, side: str, wait: float, direction: int, odo: Odometer) -> None:
        """Start the approach: the branch `side` has just shown at the window's edge column."""
        t = self.p.turning
        self.way, self.side, self.wait, self.direction = way, side, wait, direction
        self._began = None
        self._start('approach', odo)
        self._crossing = t.camera_ahead + t.detect_lead  # crossing_from thesis (App. F.6)

    def place_crossing(self, edge: float | None, half_width: float, odo: Odometer) -> None:
        """Place the crossing from the branch's near edge `edge` m ahead of the window centre.

        Only while approaching under crossing_from image, and for a frame that shows the edge.
        """
        if self.phase == 'approach' and edge is not None \
                and self.p.turning.crossing_from == 'image':
            self._crossing = self._moved(odo)[0] + self.p.turning.camera_ahead + edge \
                + half_width

    def _start(self, phase: str, odo: Odometer) -> None:
        self.phase = phase
        self._from = (odo.left, odo.right)

    def _moved(self, odo: Odometer) -> tuple[float, float]:
        """(m along travel the axle centre has moved, rad turned CCW) since the phase began."""
        left, right = odo.left - self._from[0], odo.right - self._from[1]
        return self.direction * (left + right) / 2.0, (right - left) / self.p.steering.wheel_span

    def _profile(self, distance: float, top: float) -> float:
        """Speed that comes to rest in `distance` at the turning's deceleration."""
        return min(top, math.sqrt(2.0 * self.p.turning.stop_deceleration * max(distance, 0.0)))

    def step(self, now: float, odo: Odometer, rims: tuple[float, float], speed: float,
             steer: float, law: CameraLaw) -> str:
        """Run one pass; return '' (going on), 'done' (follow the tape) or 'timeout' (stop).

        `rims` are the wheels' speeds and `speed` the axle centre's (m/s, + = forwards), from
        wheel odometry; `steer` the caster angle the frames last gave.
        """
        t = self.p.turning
        if self._began is None:
            self._began = now
        if now - self._began > t.turn_timeout + self.wait:
            # Odometry that stopped counting (or a wheel that will not turn) must not leave the
            # vehicle spinning or creeping: motors off, as for a lost tape.
            self.phase, self.wheels = '', (0.0, 0.0)
            return 'timeout'
        moving = max(abs(v) for v in rims) > AT_REST
        if self.phase == 'approach':
            remaining = self._crossing - self._moved(odo)[0]
            if abs(remaining) > t.position_tolerance or abs(speed) > 0.01:
                if remaining >= 0:  # steered by the tape, slowing to a stop over the crossing
                    top = min(t.approach_speed, self.p.camera_speed)
                    self.wheels = law.wheel_speeds(self._profile(remaining, top), steer)
                else:  # braked past it (from a high cruise): straight back onto it
                    back = -self.direction * self._profile(-remaining, t.approach_speed)
                    self.wheels = (back, back)
                return ''
            self.wheels, self._wait_until = (0.0, 0.0), now + self.wait
            self._start('wait', odo)
        if self.phase == 'wait':
            if now < self._wait_until:
                self.wheels = (0.0, 0.0)
                return ''
            if self.way == 'straight':
                self.phase = ''
                return 'done'
            self._start('spin', odo)
        if self.phase == 'spin':
            # A wheel speed profile that ends the quarter turn at rest (the drive's trapezoid
            # brakes at 0.3 m/s^2: cut short at full speed it would overshoot by ~8 deg), and
            # turns back what the wheels' lag carried it past.
            way = 1 if self.way == 'left' else -1
            error = math.radians(t.spin_angle) - way * self._moved(odo)[1]
            arc = error * self.p.steering.wheel_span / 2.0
            w = math.copysign(self._profile(abs(arc), t.spin_speed), arc) * way
            if abs(error) > math.radians(t.angle_tolerance) or moving:
                self.wheels = (-w, w)
                return ''
            self.phase, self.wheels = 'settle', (0.0, 0.0)
        if moving:
            return ''  # still turning
        self.phase = ''
        return 'done'
