"""Odometric pose from the drive wheels' speeds, and the track point under the camera.

Rajagopalan 1991, 5.4.1 (Eq. 5.30-5.39): the identification of the track's geometry places each
camera reading in the floor frame by integrating the wheel speeds sample by sample. ROS-free.

Conventions (those of the whole package): x forward and y to the left in the body frame, the
reference point O midway between the drive wheels, heading counter-clockwise from the floor's x
axis, wheel rim speeds in m/s positive forwards. The forward speed and yaw rate of O follow from
the wheels as Eq. 5.33 with equal half-spans, the yaw rate counted counter-clockwise:

    v = (v_left + v_right) / 2,    psi' = (v_right - v_left) / wheel_span

The thesis prints psi' = r (w1 - w2) / (L1 + L2): its yaw is clockwise positive. The reference
point is O itself, so Eq. 5.33's lateral speed L_d psi' is zero here.

Integration rules (`rule`):
  trapezoid        Eq. 5.38, the thesis's choice: the mean of the last two speeds, turned
                   through the heading of the previous sample.
  simpson_printed  Eq. 5.39 as printed: one sample's step taken with Simpson's weights for two
                   sample intervals, dT / 3 (f(n) + 4 f(n-1) + f(n-2)) added to the pose at n-1.
                   That counts each step about twice over; it is kept to reproduce the thesis's
                   finding that Simpson's rule did worse than the trapezoid (7.5.1.1, Fig. 7.17).
  simpson          Simpson's rule used correctly: x(n) = x(n-2) + dT / 3 (f(n) + 4 f(n-1) +
                   f(n-2)), f being the floor-frame velocity at each sample (two interleaved
                   chains, each exact to fourth order; the first step is a trapezoid). Unequal
                   sample periods take the three-point rule for unequal intervals.

The thesis measured each wheel's speed as the change of its position count over the timed
sample (7.5.2.1); `update_travel` takes exactly that, the travel of each wheel over the sample.

ChordOdometry is no rule of the thesis: each sample's own wheel travels, the heading turned by
their difference, a step along the chord. It keeps the counters' own heading, to show beside
the rules what the wheel counts themselves are worth on a turn (bench/identification_sims.py,
I1, and identification_experiments.py).
"""

from __future__ import annotations

import math

RULES = ('trapezoid', 'simpson_printed', 'simpson')


class PoseIntegrator:
    """Pose of the reference point O from the two wheels' speeds, one sample at a time.

    `left_scale` multiplies the left wheel's speed: the straight-running correction of
    Rajagopalan 1991, 7.5.2.2, where the odometric path of a truck running straight bent left
    until the left wheel's speed was taken 1.0018 times larger (the thesis prints it as
    "w2 = 1.0018 w2" and names the left wheel). In simulation the wheels are equal: 1.0.
    `v_left` and `v_right` are the speeds at the initial pose (at rest by default).
    The heading is not wrapped, so it stays continuous over whole turns.
    """

    def __init__(self, wheel_span: float, rule: str = 'trapezoid', left_scale: float = 1.0,
                 x: float = 0.0, y: float = 0.0, heading: float = 0.0,
                 v_left: float = 0.0, v_right: float = 0.0) -> None:
        if rule not in RULES:
            raise ValueError(f'rule {rule!r} is not one of {", ".join(RULES)}')
        if not wheel_span > 0.0:
            raise ValueError(f'wheel_span {wheel_span!r} must be positive')
        self.wheel_span = wheel_span
        self.rule = rule
        self.left_scale = left_scale
        self.x, self.y, self.heading = x, y, heading
        self.distance = 0.0  # m travelled by O, signed (trapezoid of the forward speed)
        self.samples = 0
        self._v1, self._w1 = self._body(v_left, v_right)  # forward speed, yaw rate at n-1
        self._v2: float | None = None  # ... at n-2
        self._w2 = 0.0
        self._pose2 = (x, y, heading)  # pose at n-2
        self._dt1 = 0.0  # the period from n-2 to n-1

    @property
    def pose(self) -> tuple[float, float, float]:
        """Return (x, y, heading) of O, m and rad."""
        return self.x, self.y, self.heading

    def _body(self, v_left: float, v_right: float) -> tuple[float, float]:
        left = self.left_scale * v_left
        return (left + v_right) / 2.0, (v_right - left) / self.wheel_span

    def update(self, v_left: float, v_right: float, dt: float) -> tuple[float, float, float]:
        """Take the wheels' rim speeds (m/s) sampled `dt` s after the previous sample.

        Returns the new pose (x, y, heading).
        """
        if not dt > 0.0:
            raise ValueError(f'sample period {dt!r} must be positive')
        v, w = self._body(v_left, v_right)
        x1, y1, h1 = self.x, self.y, self.heading
        v1, w1 = self._v1, self._w1
        if self.rule == 'simpson' and self._v2 is not None:
            # Three-point rule over [n-2, n] for intervals dt1 and dt (dT / 3 (1, 4, 1) when
            # they are equal).
            h0, span = self._dt1, self._dt1 + dt
            k0 = span / 6.0 * (2.0 - dt / h0)
            k1 = span / 6.0 * span * span / (h0 * dt)
            k2 = span / 6.0 * (2.0 - h0 / dt)
            x2, y2, h2 = self._pose2
            heading = h2 + k0 * self._w2 + k1 * w1 + k2 * w
            v2 = self._v2
            x = x2 + k0 * v2 * math.cos(h2) + k1 * v1 * math.cos(h1) + k2 * v * math.cos(heading)
            y = y2 + k0 * v2 * math.sin(h2) + k1 * v1 * math.sin(h1) + k2 * v * math.sin(heading)
        elif self.rule == 'simpson':  # its first step: a trapezoid of the floor-frame velocity
            heading = h1 + dt / 2.0 * (w + w1)
            x = x1 + dt / 2.0 * (v1 * math.cos(h1) + v * math.cos(heading))
            y = y1 + dt / 2.0 * (v1 * math.sin(h1) + v * math.sin(heading))
        elif self.rule == 'simpson_printed' and self._v2 is not None:  # Eq. 5.39
            step = dt / 3.0 * (v + 4.0 * v1 + self._v2)
            heading = h1 + dt / 3.0 * (w + 4.0 * w1 + self._w2)
            x, y = x1 + step * math.cos(h1), y1 + step * math.sin(h1)
        else:  # Eq. 5.38 (and Eq. 5.39's first step, which has no n-2)
            step = dt / 2.0 * (v + v1)
            heading = h1 + dt / 2.0 * (w + w1)
            x, y = x1 + step * math.cos(h1), y1 + step * math.sin(h1)
        self.distance += dt / 2.0 * (v + v1)
        self._pose2, self._v2, self._w2, self._dt1 = (x1, y1, h1), v1, w1, dt
        self._v1, self._w1 = v, w
        self.x, self.y, self.heading = x, y, heading
        self.samples += 1
        return x, y, heading

    def update_travel(self, d_left: float, d_right: float,
                      dt: float) -> tuple[float, float, float]:
        """Take each wheel's travel over the last sample (m, + forwards) instead of speeds.

        The travel over the sample divided by its period is the wheel's mean speed over it,
        which is how the thesis measured the speeds it integrated (Rajagopalan 1991, 7.5.2.1).
        The package's wheel_odometry counters wrap: their increments come from
        agv_nodes.odometry.counter_step (mm, so divide by 1000).
        """
        if not dt > 0.0:
            raise ValueError(f'sample period {dt!r} must be positive')
        return self.update(d_left / dt, d_right / dt, dt)


class ChordOdometry:
    """Pose of O from each wheel's travel over a sample: the counters' own heading.

    Not a rule of PoseIntegrator: no speeds and no sample period. The heading turns by each
    sample's own travel difference, (d_right - d_left) / wheel_span, the counters' heading with
    nothing averaged over two samples, and O steps the mean travel along the mean of the
    headings before and after the sample: the direction of the chord of a constant-curvature
    step, where Eq. 5.38 steps along the previous sample's heading and so lags half a sample's
    turn on a curve. The step's length is the arc's, not the chord's: on a step turning dpsi
    it is dpsi / 2 / sin(dpsi / 2) times the chord, 1 + dpsi^2 / 24, so a run of equal steps
    round a circle lies on the true path scaled by that factor about the start (6 um after a
    half lap of R = 2.95 m in 15 mm steps). Exact on a straight. For what the wheel counts
    themselves are worth on a turn (bench/identification_sims.py, I1). No left_scale: the
    travels are taken as they come. The heading is not wrapped.
    """

    def __init__(self, wheel_span: float, x: float = 0.0, y: float = 0.0,
                 heading: float = 0.0) -> None:
        if not wheel_span > 0.0:
            raise ValueError(f'wheel_span {wheel_span!r} must be positive')
        self.span, self.x, self.y, self.heading = wheel_span, x, y, heading

    @property
    def pose(self) -> tuple[float, float, float]:
        """Return (x, y, heading) of O, m and rad."""
        return self.x, self.y, self.heading

    def update(self, d_left: float, d_right: float) -> tuple[float, float, float]:
        """Take each wheel's travel over one sample (m, + forwards); return the new pose."""
        turn = (d_right - d_left) / self.span
        mid = self.heading + turn / 2.0
        step = (d_left + d_right) / 2.0
        self.x, self.y = self.x + step * math.cos(mid), self.y + step * math.sin(mid)
        self.heading += turn
        return self.x, self.y, self.heading


def track_point(x: float, y: float, heading: float, camera_ahead: float, eps_d: float,
                eps_theta: float) -> tuple[float, float, float]:
    """Return the track point P under the camera window and the track's heading there.

    Rajagopalan 1991, Eq. 5.30-5.31 with the camera window's centre B at (camera_ahead, 0) in
    the body frame: P lies eps_d from B along the body's y axis (eps_d > 0 with the tape left
    of the window's centre), and the track there is turned eps_theta from the body's x axis
    (counter-clockwise positive). So P = O + R(heading) (camera_ahead, eps_d) and
    theta_p = heading + eps_theta. The thesis's Eq. 5.31 prints theta_p = theta - eps_theta
    in its own sign of eps_theta.
    """
    c, s = math.cos(heading), math.sin(heading)
    return (x + camera_ahead * c - eps_d * s, y + camera_ahead * s + eps_d * c,
            heading + eps_theta)
