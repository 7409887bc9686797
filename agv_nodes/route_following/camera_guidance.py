"""Binary-camera guidance of Rajagopalan (1991): image analysis and steering laws, ROS-free.

Frames are 64 x 128 binary images of the floor (1 = dark tape), row 0 the leading edge and
column 0 the left edge (Rajagopalan 1991, 4.1-4.2). Signs follow Rajagopalan 1991, 5.2:
eps_d > 0 when the tape lies to the left of the window centre, eps_theta > 0 when it is turned
CCW, and the caster angle theta_s > 0 turns the vehicle left.
"""

from dataclasses import dataclass
import enum
import math

import numpy as np

from agv_nodes.route_following.settings import ImageParams, SteeringParams


class Validity(enum.Enum):
    """imageok_flag as an explicit enum (Rajagopalan 1991, 4.3)."""

    NORMAL = 'normal'
    WIDE = 'wide'  # track grew by about 2 bytes: a road sign (thesis 4.3)
    ABSENT = 'absent'  # mostly white: no track
    SATURATED = 'saturated'  # mostly dark: ignore the frame, keep the last command


@dataclass
class Measurement:
    """What one frame says about the track."""

    eps_d: float  # m
    eps_theta: float  # rad
    validity: Validity
    width_px: float  # mean accepted run length
    rows_used: int
    left_edge: bool  # column 0 dark in >= sign_rows rows
    right_edge: bool  # column 127 dark in >= sign_rows rows


SIGNS = {(1, 0, 0): 'P11', (0, 1, 0): 'P12', (1, 0, 1): 'P21', (0, 1, 1): 'P22',
         (1, 1, 0): 'R1', (1, 1, 1): 'R2'}  # (left, right, straight): Rajagopalan 1991, fig 4.3


def sign_name(left: int, right: int, straight: int) -> str | None:
    """Return the road sign a set of branch flags decodes to (thesis fig 4.3), or None."""
    return SIGNS.get((int(left), int(right), int(straight)))


def runs_of(row: np.ndarray) -> list[tuple[int, int]]:
    """Pass 1 (run-length table): (start column, length) of each dark run in a row."""
    padded = np.concatenate(([0], row.astype(np.int8), [0]))
    edges = np.flatnonzero(np.diff(padded))
    return [(int(a), int(b - a)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


class ImageAnalyser:
    """Noise filter, least-squares line fit, validity and road-sign primitives."""

    def __init__(self, params: ImageParams | None = None) -> None:
        self.p = params or ImageParams()
        self.mm_row, self.mm_col = self.p.depth / 64, self.p.width / 128
        self.normal_width = self.p.normal_width
        self._prev_centre: float | None = None

    def branch_edge(self, frame: np.ndarray, side: str) -> float | None:
        """Return how far (m) ahead of the window centre a branch's near edge is (edge column).

        The longest dark run down the column is the branch (specks are shorter); None when there is
        none or its near edge is behind the window.
        """
        column = frame[:, 0 if side == 'left' else -1]
        if not (runs := [(a, n) for a, n in runs_of(column) if n >= self.p.sign_rows]):
            return None
        a, n = max(runs, key=lambda k: k[1])
        last = a + n - 1  # rearmost dark row (row 0 is ahead)
        if last >= len(column) - 1:
            return None
        return (31.0 - last) * self.mm_row  # between row `last` and the light row behind it

    def forget_track(self) -> None:
        """Take the widest run next frame, not the one nearest the last (a new branch)."""
        self._prev_centre = None

    def _runs(self, window: np.ndarray, rows: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run passes 1 and 2 on every row at once: (row, centre column, length) of kept runs.

        Rows without a run of min_run px are left out; a row with several keeps one (Table
        4.2): the one nearest the previous frame's centre, or with none the widest, the
        leftmost on a tie. The whole window in a few array operations: a row at a time the
        passes cost ten times as much, most of a frame's analysis (bench/route_cpu_bench.py).
        """
        padded = np.zeros((window.shape[0], window.shape[1] + 2), dtype=np.int8)
        padded[:, 1:-1] = window
        row, col = np.nonzero(np.diff(padded, axis=1))  # row by row, a start then its end
        row, start, length = row[::2], col[::2], col[1::2] - col[::2]
        kept = length >= self.p.min_run
        row, start, length = row[kept], start[kept], length[kept]
        centre = start + length / 2.0
        cost = -length if self._prev_centre is None else np.abs(centre - self._prev_centre)
        order = np.lexsort((start, cost, row))  # by row, then cost, then column
        first = order[np.unique(row[order], return_index=True)[1]]
        return rows[row[first]].astype(float), centre[first], length[first]

    def analyse(self, frame: np.ndarray) -> Measurement:
        """eps_d, eps_theta and validity of one frame."""
        p = self.p
        dark_fraction = float(frame.mean())
        left = int(frame[:, 0].sum()) >= p.sign_rows
        right = int(frame[:, -1].sum()) >= p.sign_rows
        if dark_fraction > p.saturated_fraction:
            return Measurement(0.0, 0.0, Validity.SATURATED, 0.0, 0, left, right)
        rows = np.asarray(p.rows or range(64))
        ys, xs, widths = self._runs(frame[rows] if p.rows else frame, rows)
        if len(ys) < 2:
            self._prev_centre = None
            return Measurement(0.0, 0.0, Validity.ABSENT, 0.0, len(ys), left, right)
        # Well-conditioned fit (Rajagopalan 1991, 4.2.2): column on row, m from the window centre.
        y = (31.5 - ys) * self.mm_row  # + ahead
        x = (63.5 - xs) * self.mm_col  # + left
        ybar, xbar = y.mean(), x.mean()
        syy = float(((y - ybar) ** 2).sum())
        a = float(((y - ybar) * (x - xbar)).sum() / syy) if syy > 0 else 0.0
        b = float(xbar - a * ybar)
        self._prev_centre = float(np.mean(xs))
        width = float(np.mean(widths))
        if not self.normal_width:
            self.normal_width = width
        validity = Validity.WIDE if width > p.wide_factor * self.normal_width else \
            Validity.NORMAL
        return Measurement(b, math.atan(a), validity, width, len(ys), left, right)


class CameraSteering:
    """P / PI steering on (eps_d, eps_theta) and its conversion to wheel speeds."""

    def __init__(self, params: SteeringParams | None = None, camera: float = 0.64) -> None:
        self.p = params or SteeringParams()
        self.integral = self.theta_s = 0.0
        self.plain_theta = 0.0  # rad: eps_theta of the last frame with a plain tape
        self.absent = 0
        self.predictor = WindowPredictor(self.p, camera)

    def update(self, m: Measurement, dt: float, speed: float = 0.0) -> float | None:
        """Return the caster angle theta_s at cruise `speed`; None (stop): the track is absent."""
        p = self.p
        gain_d = p.gain_d
        if p.schedule_speed > 0 and speed > p.schedule_speed:
            gain_d *= p.schedule_speed / speed
        self.predictor.advance(dt)
        if m.validity is Validity.ABSENT:
            self.absent += 1
            self.predictor.forget()
            return None if self.absent >= p.absent_frames else self.theta_s
        self.absent = 0
        if m.validity is Validity.SATURATED:
            return self.theta_s  # ignore the frame: steer from the previous data
        eps_theta, plain = m.eps_theta, m.validity is Validity.NORMAL
        if plain:
            self.plain_theta = eps_theta
        else:
            # A road sign under the window (4.3): its patch and branches turn the fitted line by
            # tens of degrees at a branch, which is not the tape's orientation; fed back, it
            # steers the truck onto the branch. The last plain frame's orientation stands.
            eps_theta = self.plain_theta
        eps_d, eps_theta = self.predictor.predict(m.eps_d, eps_theta, dt, speed, plain)
        if p.law == 'pi':  # Eq 5.6 (G1 on eps_theta, G2 on eps_d, G3 on the integral)
            if not p.integral_band or abs(m.eps_d) < p.integral_band:
                self.integral += (dt if p.integral_form == 'with_dt' else 1.0) * m.eps_d
            theta = p.gain_theta * eps_theta + gain_d * eps_d + p.gain_i * self.integral
        else:  # Eq 5.4
            theta = gain_d * eps_d + p.gain_theta * eps_theta
        self.theta_s = max(-p.max_angle, min(p.max_angle, theta))
        self.predictor.asked(self.theta_s, speed)
        return self.theta_s

    def wheel_speeds(self, speed: float, theta_s: float) -> tuple[float, float]:
        """Eq 5.10-5.16: left and right rim speeds for cruise `speed` and caster angle."""
        p = self.p
        lae = p.caster_distance + p.caster_trail * (1.0 - math.cos(theta_s))  # Eq 5.11
        yaw_rate = speed * math.tan(theta_s) / lae  # Eq 5.10
        half = yaw_rate * p.wheel_span / 2.0  # Eq 5.12
        return speed - half, speed + half  # Eq 5.13-5.14 (a left turn speeds up the right)


class WindowPredictor:
    """The window's offsets `predict` s ahead, for the frame's and the wheels' delays (ours).

    Not the thesis's. The window sits L_c ahead of the axle; with the tape turned alpha
    (eps_theta) from the truck and the truck turning at yaw rate w, the tape turns under the
    window at d(alpha)/dt = kappa v - w, kappa the tape's curvature there, and the window moves
    across it at d(eps_d)/dt = v sin(alpha) - L_c w. The yaw rate is estimated from the angles
    asked for (Eq. 5.10-5.11 at cruise) through a first-order lag of wheel_lag s; the tape's
    curvature from each frame's change of alpha plus that yaw rate, filtered (a share
    curvature_filter of each frame's reading). The law then steers the offsets the window will
    show `predict` s on: a curve's start turns the wheels before the window has run off it.
    The yaw rate estimated from the angles asked, not the one measured by wheel odometry: on
    the dynamic model, whose wheels lag most, the curvature from the measured turn left a
    larger peak on the S-bend R 3 m, 0.6 m, R 2 m at 0.79 m/s (14 against 13 mm, run as
    bench/concic2_curvature_bench.py runs its S-bends).
    """

    def __init__(self, params: SteeringParams, camera: float) -> None:
        self.p, self.camera = params, camera
        self.rate = self.command = 0.0  # rad/s: the wheels' estimated and the last asked
        self.kappa = 0.0  # 1/m, filtered
        self._alpha: float | None = None  # the last frame's eps_theta

    def forget(self) -> None:
        """Forget the last frame's angle (the tape left the window; a new start)."""
        self._alpha = None

    def reset(self) -> None:
        """Start from rest on a straight."""
        self.rate = self.command = self.kappa = 0.0
        self._alpha = None

    def advance(self, dt: float) -> None:
        """Move the estimated yaw rate on by `dt` s towards the last one asked for."""
        if self.p.wheel_lag > 0:
            self.rate += (self.command - self.rate) * (1.0 - math.exp(-dt / self.p.wheel_lag))
        else:
            self.rate = self.command

    def predict(self, eps_d: float, eps_theta: float, dt: float, speed: float,
                plain: bool = True) -> tuple[float, float]:
        """Return (eps_d, eps_theta) `predict` s on; as measured with predict 0.

        `plain`: the frame shows plain tape. Over a road sign no curvature is read (the patch
        turns the fit, not the tape), and the next plain frame starts the reading afresh.
        """
        p = self.p
        ahead = p.predict > 0 and speed > 0
        if ahead and plain and self._alpha is not None:
            reading = ((eps_theta - self._alpha) / dt + self.rate) / speed
            # A road sign's patch and branches turn the fitted line by degrees in a frame: a
            # reading of tens per m. No tape the window can stay on is curved beyond 1 / L_c.
            bound = 1.0 / self.camera
            reading = max(-bound, min(bound, reading))
            self.kappa += p.curvature_filter * (reading - self.kappa)
        self._alpha = eps_theta if plain else None
        if not ahead:
            return eps_d, eps_theta
        h = p.predict
        alpha = eps_theta + h * (self.kappa * speed - self.rate)
        eps_d += h * (speed * math.sin(0.5 * (eps_theta + alpha)) - self.camera * self.rate)
        return eps_d, alpha

    def asked(self, theta_s: float, speed: float) -> None:
        """Note the caster angle asked for at cruise `speed` (its yaw rate, Eq. 5.10-5.11)."""
        p = self.p
        lae = p.caster_distance + p.caster_trail * (1.0 - math.cos(theta_s))
        self.command = speed * math.tan(theta_s) / lae
