"""Least-squares identification of the track from the points P under the camera.

Rajagopalan 1991, 5.4.2 (Eq. 5.42-5.62): the points P (pose.track_point) seen so far are fitted
by three models, refreshed every sample, and each is eliminated to an implicit curve
A x^2 + B x y + C y^2 + D x + E y + F = 0 for the feed-forward law; track_fitter.py chooses
the one in use. ROS-free.

Each fit keeps the sums of its normal equations, sum(z z^T) with z = (1, regressors, targets),
taken about its first sample (to keep their precision): a sample costs O(1). The small system
is solved when a result is asked for; None while it is singular or badly conditioned. With a
sliding window (`window`, m of travel) a leaving sample's terms are subtracted, and the sums are
retaken from the kept samples once their origin lags a window behind (amortised O(1)).

The thesis's printed solutions take the intercept from the means after the slopes, the least
squares fit only when the regressors have zero mean: these are the full 3-parameter fits.
Residual RMS values are per coordinate over the degrees of freedom (2n - 6 for the parametric
fits, n - 2 for the line, whose residual is the distance across it): one scale for all models.
"""

from __future__ import annotations

from collections import deque
import math
from typing import NamedTuple

import numpy as np

Conic = tuple[float, float, float, float, float, float]  # A, B, C, D, E, F


class Sample(NamedTuple):
    s: float  # m travelled
    x: float
    y: float
    theta: float = 0.0  # the track's heading at P


def shift_conic(conic: Conic, x0: float, y0: float) -> Conic:
    """Return f(x - x0, y - y0) for the conic f: the curve moved by (x0, y0)."""
    A, B, C, D, E, F = conic
    return (A, B, C, D - 2 * A * x0 - B * y0, E - 2 * C * y0 - B * x0,
            F + A * x0 * x0 + B * x0 * y0 + C * y0 * y0 - D * x0 - E * y0)


def ellipse_of(conic: Conic) -> tuple[float, float, float, float, float] | None:
    """Return (centre x, centre y, semi-major, semi-minor, major axis angle) of a real ellipse.

    None when the conic is no real ellipse. The angle is in (-pi/2, pi/2].
    """
    A, B, C, D, E, F = conic
    det = 4 * A * C - B * B
    if not det > 0.0:
        return None
    xc, yc = (B * E - 2 * C * D) / det, (B * D - 2 * A * E) / det
    level = F + (D * xc + E * yc) / 2.0  # f at the centre
    if A + C < 0.0:  # make the quadratic part positive definite
        A, B, C, level = -A, -B, -C, -level
    if not level < 0.0:
        return None
    lam, vec = np.linalg.eigh(np.array([[A, B / 2.0], [B / 2.0, C]]))
    angle = math.atan2(vec[1, 0], vec[0, 0])  # the smaller eigenvalue's: the major axis
    angle = math.pi / 2 - (math.pi / 2 - angle) % math.pi
    return xc, yc, math.sqrt(-level / lam[0]), math.sqrt(-level / lam[1]), angle


class _Fit:
    """The normal equations of one model, kept up to date in O(1) per sample."""

    regressors = 3  # p, the constant included
    targets = 2

    def __init__(self, window: float | None = None, max_condition: float = 1e10) -> None:
        if window is not None and not window > 0.0:
            raise ValueError(f'window {window!r} must be positive (None: all samples)')
        self.window, self.max_condition = window, max_condition
        self.reset()

    def reset(self) -> None:
        """Forget every sample."""
        size = self.regressors + self.targets
        self._sums = np.zeros((size, size))
        self._origin: Sample | None = None
        self._last: Sample | None = None
        self._kept: deque[Sample] = deque()
        self._cache: tuple[np.ndarray | None] | None = None

    @property
    def _base(self) -> Sample:
        """The origin the sums are taken about: the first sample kept."""
        if self._origin is None:
            raise RuntimeError('a fit without samples has no origin')
        return self._origin

    @property
    def n(self) -> int:
        """Samples in the fit."""
        return round(self._sums[0, 0])

    def _row(self, p: Sample) -> np.ndarray:
        raise NotImplementedError

    def _add(self, p: Sample) -> None:
        if self._origin is None:
            self._origin = p
        z = self._row(p)
        self._sums += np.outer(z, z)
        self._last, self._cache = p, None
        if self.window is None:
            return
        self._kept.append(p)
        while p.s - self._kept[0].s > self.window:
            z = self._row(self._kept.popleft())
            self._sums -= np.outer(z, z)
        if self._kept[0].s - self._base.s > self.window:
            self._origin = self._kept[0]
            rows = np.array([self._row(q) for q in self._kept])
            self._sums = rows.T @ rows

    def _solution(self) -> np.ndarray | None:
        if self._cache is None:
            self._cache = (self._solve(),)
        return self._cache[0]

    def _solve(self) -> np.ndarray | None:
        """Coefficients about the origin, one column per target; None while unsolvable."""
        p = self.regressors
        if self.n < p:
            return None
        normal, rhs = self._sums[:p, :p], self._sums[:p, p:]
        scale = np.sqrt(np.diag(normal))
        if not np.all(scale > 0.0):
            return None
        scaled = normal / np.outer(scale, scale)  # unit diagonal: the condition of the shape
        sv = np.linalg.svd(scaled, compute_uv=False)
        if not sv[-1] * self.max_condition > sv[0]:
            return None
        return np.linalg.solve(scaled, rhs / scale[:, None]) / scale[:, None]

    @property
    def ready(self) -> bool:
        """Whether the fit has a solution."""
        return self._solution() is not None

    def _rss(self) -> float | None:
        c, p, sums = self._solution(), self.regressors, self._sums
        if c is None:
            return None
        fitted = np.einsum('ij,ik,kj->j', c, sums[:p, :p], c)
        return max(float(np.sum(np.diag(sums)[p:] - 2.0 * np.sum(c * sums[:p, p:], 0) + fitted)),
                   0.0)

    def _dof(self) -> int:
        return self.targets * (self.n - self.regressors)

    @property
    def residual_rms(self) -> float | None:
        """RMS residual per coordinate over the degrees of freedom, m (None: no fit yet)."""
        rss, dof = self._rss(), self._dof()
        return math.sqrt(rss / dof) if rss is not None and dof > 0 else None


class _Parametric(_Fit):
    """x and y each fitted on (1, g1, g2) of the sample: the polynomial and conic models."""

    def _g(self, p: Sample) -> tuple[float, float]:
        raise NotImplementedError

    def _row(self, p: Sample) -> np.ndarray:
        origin = self._base
        return np.array([1.0, *self._g(p), p.x - origin.x, p.y - origin.y])

    def _at(self, p: Sample) -> tuple[float, float] | None:
        c = self._solution()
        if c is None:
            return None
        x, y = np.array([1.0, *self._g(p)]) @ c
        return float(self._base.x + x), float(self._base.y + y)

    def _absolute(self, shift: np.ndarray) -> tuple[float, float, float, float, float, float]:
        """(a0, a1, a2, b0, b1, b2) from those about the origin, `shift` moving g's origin."""
        if (solution := self._solution()) is None:
            raise RuntimeError('coefficients of a fit without a solution')
        c = shift @ solution + [[self._base.x, self._base.y], [0.0, 0.0], [0.0, 0.0]]
        a0, a1, a2, b0, b1, b2 = (float(v) for v in c.T.ravel())
        return a0, a1, a2, b0, b1, b2

    def error(self, p: Sample) -> float | None:
        """Distance of the sample's point from the fitted point at its s or theta, m."""
        return None if (at := self._at(p)) is None else math.hypot(p.x - at[0], p.y - at[1])


class PolynomialFit(_Parametric):
    """x = a0 + a1 s + a2 s^2, y = b0 + b1 s + b2 s^2 in travelled distance s (Eq. 5.53-5.54).

    The thesis's parameter is V t, the distance at constant speed; here the caller's s (the
    odometer's), which keeps the fit independent of speed as the thesis intended.
    """

    def _g(self, p: Sample) -> tuple[float, float]:
        ds = p.s - self._base.s
        return ds, ds * ds

    def add(self, x: float, y: float, s: float) -> None:
        """Take the point P = (x, y) reached at travelled distance s."""
        self._add(Sample(s, x, y))

    @property
    def coefficients(self) -> tuple[float, float, float, float, float, float] | None:
        """Return (a0, a1, a2, b0, b1, b2) in the caller's s, or None while unsolvable."""
        if not self.ready:
            return None
        s0 = self._base.s
        return self._absolute(np.array([[1.0, -s0, s0 * s0], [0.0, 1.0, -2 * s0], [0, 0, 1.0]]))

    def point(self, s: float) -> tuple[float, float] | None:
        """Return the fitted (x, y) at travelled distance s."""
        return self._at(Sample(s, 0.0, 0.0))

    def derivatives(self, s: float) -> tuple[float, float, float, float] | None:
        """Return (dx/ds, dy/ds, d2x/ds2, d2y/ds2) of the fitted curve at s."""
        if (c := self._solution()) is None:
            return None
        (dx, dy), (ddx, ddy) = c[1] + 2 * c[2] * (s - self._base.s), 2 * c[2]
        return float(dx), float(dy), float(ddx), float(ddy)

    def implicit(self) -> Conic | None:
        """Return the fitted curve with s eliminated, as a conic of unit norm.

        With u = x - a0, w = y - b0, D1 = a1 b2 - a2 b1 and q = b2 u - a2 w, the fit gives
        q = D1 s and a1 w - b1 u = D1 s^2, so q^2 = D1 (a1 w - b1 u): a parabola. Eq. 5.57
        (cleanly: a2 q^2 + a1 D1 q - D1^2 u = 0) is this times a2, which vanishes identically
        when a2 = 0; this form does not. When D1 vanishes the fit is a straight line, given
        as one (A = B = C = 0).
        """
        if (c := self._solution()) is None:
            return None
        (a0, b0), (a1, b1), (a2, b2) = c  # about the origin: the shift comes last
        d1 = a1 * b2 - a2 * b1
        if abs(d1) <= 1e-9 * math.hypot(a1, b1) * math.hypot(a2, b2):
            dx, dy = (a1, b1) if math.hypot(a1, b1) > 0.0 else (a2, b2)
            if dx == dy == 0.0:
                return None
            conic = (0.0, 0.0, 0.0, -dy, dx, dy * a0 - dx * b0)
        else:
            k = a2 * b0 - b2 * a0
            conic = (b2 * b2, -2 * a2 * b2, a2 * a2, 2 * k * b2 + d1 * b1,
                     -2 * k * a2 - d1 * a1, k * k + d1 * (a1 * b0 - b1 * a0))
        out = np.array(shift_conic(conic, self._base.x, self._base.y))
        A, B, C, D, E, F = (float(v) for v in out / np.linalg.norm(out))
        return A, B, C, D, E, F


class ConicFit(_Parametric):
    """x = a0 + a1 cos(theta_p) + a2 sin(theta_p), y likewise in b (Eq. 5.42-5.43).

    theta_p is the track's heading at P. The curve is the unit circle mapped by the matrix
    [[a1, a2], [b1, b2]] and moved to (a0, b0): always an ellipse (the thesis's hyperbolas
    cannot come out of it), and theta_p is its tangent's angle only when it is a circle. So an
    ellipse is approximated, the more coarsely the more eccentric it is.
    """

    def _g(self, p: Sample) -> tuple[float, float]:
        return math.cos(p.theta), math.sin(p.theta)

    def add(self, x: float, y: float, theta_p: float, s: float) -> None:
        """Take the point P = (x, y), the track's heading there and the distance travelled."""
        self._add(Sample(s, x, y, theta_p))

    @property
    def coefficients(self) -> tuple[float, float, float, float, float, float] | None:
        """Return (a0, a1, a2, b0, b1, b2), or None while unsolvable."""
        return self._absolute(np.eye(3)) if self.ready else None

    def point(self, theta_p: float) -> tuple[float, float] | None:
        """Return the fitted (x, y) where the track's heading is theta_p."""
        return self._at(Sample(0.0, 0.0, 0.0, theta_p))

    def implicit(self) -> Conic | None:
        """Return the conic with theta_p eliminated (Eq. 5.45-5.50, divided by Delta^2).

        u = x - a0, w = y - b0, Delta = a1 b2 - a2 b1: then cos(theta_p) = (b2 u - a2 w) /
        Delta and sin(theta_p) = (a1 w - b1 u) / Delta, whose squares add to one. The thesis's
        Eq. 5.49 squares the denominators by mistake.
        """
        if (k := self.coefficients) is None:
            return None
        a0, a1, a2, b0, b1, b2 = k
        A, B, C = b1 * b1 + b2 * b2, -2 * (a1 * b1 + a2 * b2), a1 * a1 + a2 * a2
        delta = a1 * b2 - a2 * b1
        return (A, B, C, -2 * A * a0 - B * b0, -2 * C * b0 - B * a0,
                A * a0 * a0 + B * a0 * b0 + C * b0 * b0 - delta * delta)

    def circle(self) -> tuple[float, float, float] | None:
        """Return (centre x, centre y, radius): (a0, b0, sqrt|Delta|), of equal area."""
        k = self.coefficients
        return None if k is None else (k[0], k[3], math.sqrt(abs(k[1] * k[5] - k[2] * k[4])))

    def ellipse(self) -> tuple[float, float, float, float, float] | None:
        """Return (centre x, centre y, semi-major, semi-minor, angle) from the implicit form."""
        return None if (conic := self.implicit()) is None else ellipse_of(conic)


class LineFit(_Fit):
    """A straight line through the points P (Eq. 5.59-5.62).

    `form`: tls, total least squares (the line of least squared distance, any direction);
    swap, y = m x + c or x = m' y + c', whichever axis the points spread along more; plain,
    the thesis's y = m x + c of Eq. 5.62, which has no solution on a line along y and huge
    slopes near one (as at the start of Rajagopalan 1991, 7.5.1.3).
    """

    regressors = 1  # the sums are those of (1, x, y)
    FORMS = ('tls', 'swap', 'plain')

    def __init__(self, window: float | None = None, max_condition: float = 1e10,
                 form: str = 'tls') -> None:
        if form not in self.FORMS:
            raise ValueError(f'form {form!r} is not one of {", ".join(self.FORMS)}')
        self.form = form
        super().__init__(window, max_condition)

    def _row(self, p: Sample) -> np.ndarray:
        origin = self._base
        return np.array([1.0, p.x - origin.x, p.y - origin.y])

    def add(self, x: float, y: float, s: float) -> None:
        """Take the point P = (x, y) reached at travelled distance s."""
        self._add(Sample(s, x, y))

    def _solve(self) -> np.ndarray | None:
        """(nx, ny, d, rss) about the origin: nx x + ny y = d with a unit normal."""
        n = self.n
        if n < 2:
            return None
        mean = self._sums[0, 1:] / n
        cov = self._sums[1:, 1:] - n * np.outer(mean, mean)
        (cxx, cxy), (_, cyy) = cov
        if self.form == 'tls':
            lam, vec = np.linalg.eigh(cov)
            # A spread along the line lost in the sums' rounding gives no direction.
            if not lam[1] > 1e-14 * np.trace(self._sums[1:, 1:]):
                return None
            normal, rss = vec[:, 0], lam[0]
        elif self.form == 'plain' or cxx >= cyy:
            if not cxx > 0.0:
                return None
            m = cxy / cxx
            normal, rss = np.array([-m, 1.0]), cyy - cxy * m
        else:
            m = cxy / cyy
            normal, rss = np.array([1.0, -m]), cxx - cxy * m
        if self.form != 'tls':
            length = float(np.hypot(*normal))
            normal, rss = normal / length, rss / length ** 2
        return np.array([normal[0], normal[1], normal @ mean, max(float(rss), 0.0)])

    def _rss(self) -> float | None:
        return None if (c := self._solution()) is None else float(c[3])

    def _dof(self) -> int:
        return self.n - 2

    @property
    def normal_form(self) -> tuple[float, float, float] | None:
        """Return (nx, ny, d): the line nx x + ny y = d, (nx, ny) a unit vector."""
        if (c := self._solution()) is None:
            return None
        nx, ny, d = (float(v) for v in c[:3])
        return nx, ny, d + nx * self._base.x + ny * self._base.y

    @property
    def slope_intercept(self) -> tuple[float, float] | None:
        """Return (m, c) of y = m x + c; None without a fit or for a line along y."""
        line = self.normal_form
        if line is None or line[1] == 0.0:
            return None
        nx, ny, d = line
        return -nx / ny, d / ny

    @property
    def heading(self) -> float | None:
        """Return the line's direction, rad, pointing from the oldest sample to the latest."""
        if (line := self.normal_form) is None:
            return None
        dx, dy = line[1], -line[0]
        origin, last = self._base, self._last
        if last is None:  # set with the origin, by the first sample
            raise RuntimeError('a fit with an origin but no latest sample')
        if dx * (last.x - origin.x) + dy * (last.y - origin.y) < 0.0:
            dx, dy = -dx, -dy
        return math.atan2(dy, dx)

    def error(self, p: Sample) -> float | None:
        """Distance of the sample's point from the line, m."""
        line = self.normal_form
        return None if line is None else abs(line[0] * p.x + line[1] * p.y - line[2])

    def implicit(self) -> Conic | None:
        """Return the line as a conic (A = B = C = 0)."""
        line = self.normal_form
        return None if line is None else (0.0, 0.0, 0.0, line[0], line[1], -line[2])
