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
crossing. Where the tape ends at the sign (P11, P12, R1) the leading window runs past its end
before the axle reaches the crossing: its last frames show one branch alone, and a caster angle
steered from them (10-20 deg) and held to the crossing brings the vehicle there turned as much,
so that the quarter turn leaves the window beside the branch. Under approach_steer `line` (the
default) the approach follows instead the tape's line as the plain frames before the sign gave
it (TapeLine: the window's tape points placed by wheel odometry, a least-squares line), with the
P law on the offset of a window L_c ahead of the axle from that line; and the spin turns a
quarter turn from that line, not from wherever the approach left the body pointing. Under
`frames` the approach steers by each frame to the crossing, and the spin turns from the arrival
heading.
"""

from collections import deque
import math

from agv_nodes.odometry import Odometer
from agv_nodes.route_following.camera_law import CameraLaw
from agv_nodes.route_following.settings import RouteParams

AT_REST = 0.005  # m/s of each wheel under which the vehicle counts as at rest
MIN_POINTS = 5  # plain frames the line needs (fewer: the approach steers by the frames)


class TapeLine:
    """The leading window's tape points in the frame of travel by wheel odometry, and a line.

    Dead reckoning from the wheels' travel (midpoint rule), x along travel at the leg's start
    (or the last spin's end) and y to its left; it counts the same whichever way the vehicle
    goes, since the frame of travel turns with the body (camera_law.py).
    """

    def __init__(self, params: RouteParams) -> None:
        self.p = params
        self.pose = (0.0, 0.0, 0.0)  # x, y (m), heading (rad, CCW) of the axle centre
        self.points: deque[tuple[float, float, float]] = deque()  # (travel, x, y)
        self._travel = 0.0
        self._last: tuple[float, float] | None = None
        self.direction = 1

    def reset(self, odo: Odometer, direction: int) -> None:
        """Forget the points (a new leg, or a branch after a spin)."""
        self.points.clear()
        self.direction = direction
        self._last = (odo.left, odo.right)

    def update(self, odo: Odometer) -> tuple[float, float, float]:
        """Advance the pose to the odometer's reading; return it."""
        if self._last is None:
            self._last = (odo.left, odo.right)
        left, right = odo.left - self._last[0], odo.right - self._last[1]
        self._last = (odo.left, odo.right)
        ds = self.direction * (left + right) / 2.0
        turn = (right - left) / self.p.steering.wheel_span
        x, y, psi = self.pose
        mid = psi + turn / 2.0
        self.pose = (x + ds * math.cos(mid), y + ds * math.sin(mid), psi + turn)
        self._travel += abs(ds)
        return self.pose

    def saw(self, eps_d: float, odo: Odometer) -> None:
        """Take a plain frame's offset: the tape's point at the window centre."""
        x, y, psi = self.update(odo)
        ahead = self.p.turning.camera_ahead
        self.points.append((self._travel, x + ahead * math.cos(psi) - eps_d * math.sin(psi),
                            y + ahead * math.sin(psi) + eps_d * math.cos(psi)))
        while self.points and self._travel - self.points[0][0] > self.p.turning.line_length:
            self.points.popleft()

    def fit(self) -> tuple[float, float, float] | None:
        """Return the tape's line as (x, y, heading along travel), or None (too few points)."""
        if len(self.points) < MIN_POINTS:
            return None
        xs = [q[1] for q in self.points]
        ys = [q[2] for q in self.points]
        mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
        sxx = sum((a - mx) ** 2 for a in xs)
        syy = sum((b - my) ** 2 for b in ys)
        sxy = sum((a - mx) * (b - my) for a, b in zip(xs, ys, strict=True))
        angle = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # the principal axis
        travel = math.atan2(ys[-1] - ys[0], xs[-1] - xs[0])
        if math.cos(angle - travel) < 0:  # the axis's sense along travel
            angle += math.pi
        return mx, my, angle

    def offset(self, line: tuple[float, float, float]) -> float:
        """Return how far (m) left of travel the line is at a window L_c ahead of the axle."""
        x, y, psi = self.pose
        ahead = self.p.turning.camera_ahead
        wx, wy = x + ahead * math.cos(psi), y + ahead * math.sin(psi)
        lx, ly, heading = line
        return (wx - lx) * math.sin(heading) - (wy - ly) * math.cos(heading)  # eps_d's sense


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
        self._from_heading = 0.0  # rad, the trace's heading when the phase began
        self._crossing = 0.0  # m of travel from the phase's start to the crossing
        self._began: float | None = None  # sim time of the manoeuvre's first pass
        self._wait_until = 0.0
        self.trace = TapeLine(params)
        self._line: tuple[float, float, float] | None = None  # the tape's line, approach_steer

    def begin(self, way: str, side: str, wait: float, direction: int, odo: Odometer) -> None:
        """Start the approach: the branch `side` has just shown at the window's edge column."""
        t = self.p.turning
        self.way, self.side, self.wait, self.direction = way, side, wait, direction
        self._began = None
        self._start('approach', odo)
        self._crossing = t.camera_ahead + t.detect_lead  # crossing_from thesis (App. F.6)
        self.trace.update(odo)
        self._line = self.trace.fit() if t.approach_steer == 'line' else None

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
        self._from_heading = self.trace.update(odo)[2]

    def _moved(self, odo: Odometer) -> tuple[float, float]:
        """(m along travel the axle centre has moved, rad turned CCW) since the phase began."""
        left, right = odo.left - self._from[0], odo.right - self._from[1]
        return self.direction * (left + right) / 2.0, (right - left) / self.p.steering.wheel_span

    def _profile(self, distance: float, top: float) -> float:
        """Speed that comes to rest in `distance` at the turning's deceleration.

        Near the end it falls as distance / settle_time: the square root's gain grows without
        bound as the distance shrinks, and behind a wheel loop slower than the kinematic
        model's (the LM628 loops of the dynamic one trail by ~0.16 s) it hunts about the end.
        """
        t = self.p.turning
        speed = min(top, math.sqrt(2.0 * t.stop_deceleration * max(distance, 0.0)))
        return min(speed, max(distance, 0.0) / t.settle_time) if t.settle_time > 0 else speed

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
        self.trace.update(odo)
        if self.phase == 'approach':
            remaining = self._crossing - self._moved(odo)[0]
            if abs(remaining) > t.position_tolerance or abs(speed) > 0.01:
                if remaining >= 0:  # steered by the tape, slowing to a stop over the crossing
                    top = min(t.approach_speed, self.p.camera_speed)
                    if self._line is not None:  # the P law on the line, not on the frames
                        s = self.p.steering
                        steer = max(-s.max_angle, min(s.max_angle,
                                                      s.gain_d * self.trace.offset(self._line)))
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
            if self._line is not None:  # a quarter turn from the tape's line
                error -= way * (self._from_heading - self._line[2])
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
