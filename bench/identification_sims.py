"""The simulations of the identification bench (Rajagopalan 1991, 7.5.1, I1-I7).

From the identification core alone (agv_nodes/track_geometry): I1 integrates each CONCIC-II
model's wheel speeds by each rule of PoseIntegrator and by ChordOdometry; I2-I7 feed exact
points of the thesis's curves (a polynomial profile, a straight line, a circle, an ellipse),
with or without the 3 mm of noise across the track, to the fits of fitting.py. Also the
thesis's constants of these runs, the convergence criterion (settle) and the sampled curves,
which the experiments (identification_experiments.py) share. The tables and notes are
identification_bench.py's.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
import math
import statistics

from concic2_thesis_bench import VEHICLES
import numpy as np

from agv_nodes.track_geometry.fitting import ConicFit, LineFit, PolynomialFit
from agv_nodes.track_geometry.pose import RULES, ChordOdometry, PoseIntegrator
from agv_nodes.track_geometry.settings import IdentificationParams
from agv_nodes.track_geometry.track_fitter import TrackFitter
from agv_nodes.world.settings import WorldParams

V, DT = 0.3, 0.05  # m/s and s of the thesis's simulations (7.5.1)
NOISE = 0.003  # m across the track: the 3-row eps_d error (Rajagopalan 1991, 8.3)
WITHIN = 0.01  # the convergence band, a fraction of the true value
LENGTH = 6.0  # m of the line runs (I3, I6, I7): 400 samples at 0.3 m/s and 50 ms
I2 = (-3.0, -5.0, 5.0, -2.0, -3.0, 1.0)  # a0, a1, a2, b0, b1, b2 (7.5.1.2)
I2_THESIS = (2.6, 1.0, 0.1, 2.5, 1.0, 0.1)  # % after 400 samples (7.5.1.2)
I3_SLOPE, I3_INTERCEPT = 1.333, 2.0  # y = m x + c (7.5.1.3)


def settle(errors: Sequence[float | None], within: float = WITHIN) -> float:
    """Return the sample (counted from 1) from which every error is <= within; inf if none.

    None (no fit yet) counts as outside.
    """
    for k in range(len(errors) - 1, -1, -1):
        if errors[k] is None or not errors[k] <= within:
            return math.inf if k == len(errors) - 1 else float(k + 2)
    return 1.0


def median(values: Sequence[float]) -> float:
    """Return the median (an inf counts as the largest)."""
    return statistics.median(values)

# -- I1: pose integration against the vehicle model's own path -----------------------------------

def i1(vehicle: str) -> dict[str, tuple[float, float]]:
    """Lateral error (mm) after 1.5 m and the largest on the way, per rule, for one model.

    Rules: those of PoseIntegrator, and 'travel', the trapezoid fed each wheel's travel over
    the sample (how the experiments are fed) instead of its speed at the sample. 'turned' is
    (heading turned, rad; distance, m) at the end.
    """
    world = WorldParams()
    p = world.concic2
    span, sub = p.wheel_span, 1.0 / (world.sample_rate * world.substeps)
    per_sample = round(DT / sub)
    truck = VEHICLES[vehicle](p)
    truck.set_wheels(V, V, True)
    for _ in range(round(3.0 / sub)):  # from rest to cruise, straight
        truck.step(sub)
    s = truck.state
    s.x = s.y = s.distance = 0.0
    s.heading = math.pi / 2  # along Y, as the thesis's run
    left, right = truck.wheel_speeds()
    fits = {rule: PoseIntegrator(span, rule, heading=s.heading, v_left=left, v_right=right)
            for rule in RULES}
    fits['travel'] = PoseIntegrator(span, 'trapezoid', heading=s.heading, v_left=left,
                                    v_right=right)
    fits['chord'] = ChordOdometry(span, 0.0, 0.0, s.heading)
    period = 1.5 / V
    worst = dict.fromkeys(fits, 0.0)
    after = dict.fromkeys(fits, 0.0)
    t = 0.0
    while s.distance < 1.5:
        d_left = d_right = 0.0
        for k in range(per_sample):
            if k % world.substeps == 0:  # a new demand every world sample
                yaw = 0.2 * math.sin(math.pi * (t + k * sub) / period)
                truck.set_wheels(V - yaw * span / 2.0, V + yaw * span / 2.0, True)
            truck.step(sub)
            left, right = truck.wheel_speeds()
            d_left, d_right = d_left + left * sub, d_right + right * sub
        t += DT
        for rule, fit in fits.items():
            if rule == 'chord':
                x, y, _ = fit.update(d_left, d_right)
            elif rule == 'travel':
                x, y, _ = fit.update_travel(d_left, d_right, DT)
            else:
                x, y, _ = fit.update(left, right, DT)
            after[rule] = 1000.0 * (-math.sin(s.heading) * (x - s.x)
                                    + math.cos(s.heading) * (y - s.y))
            worst[rule] = max(worst[rule], abs(after[rule]))
    out = {rule: (abs(after[rule]), worst[rule]) for rule in fits}
    out['turned'] = (s.heading - math.pi / 2, s.distance)
    return out


# -- exact curves and their samples ---------------------------------------------------------------

@dataclass
class Point:
    """A point P of the track, the track's heading there and the distance travelled."""

    x: float
    y: float
    theta: float
    s: float


def across(point: Point, rng: np.random.Generator | None) -> Point:
    """Return `point` moved across the track by the 3 mm noise (none without `rng`)."""
    if rng is None:
        return point
    e = NOISE * float(rng.standard_normal())
    return Point(point.x - e * math.sin(point.theta), point.y + e * math.cos(point.theta),
                 point.theta, point.s)


def i2_points(n: int) -> Iterator[Point]:
    """Yield the polynomial profile of 7.5.1.2 at s = V t (its parameter, not its arc length)."""
    a0, a1, a2, b0, b1, b2 = I2
    for k in range(n):
        s = k * V * DT
        theta = math.atan2(b1 + 2 * b2 * s, a1 + 2 * a2 * s)
        yield Point(a0 + a1 * s + a2 * s * s, b0 + b1 * s + b2 * s * s, theta, s)


def line_points(speed: float, dt: float) -> Iterator[Point]:
    """Y = 1.333 x + 2 from x = 0 for LENGTH m, a sample every `dt` s at `speed`."""
    heading = math.atan(I3_SLOPE)
    for k in range(int(LENGTH / (speed * dt) + 1e-9) + 1):
        s = k * speed * dt
        yield Point(s * math.cos(heading), I3_INTERCEPT + s * math.sin(heading), heading, s)


def circle_points(n: int, radius: float = 3.0) -> Iterator[Point]:
    """X^2 + Y^2 = radius^2 counter-clockwise from (radius, 0) at V, every DT."""
    for k in range(n):
        s = k * V * DT
        phi = s / radius
        yield Point(radius * math.cos(phi), radius * math.sin(phi), phi + math.pi / 2, s)


def ellipse_arc(a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """(parameter, arc length) of x = a cos(phi), y = b sin(phi) over one lap, finely."""
    phis = np.linspace(0.0, 2 * math.pi, 200001)
    speed = np.hypot(a * np.sin(phis), b * np.cos(phis))
    return phis, np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2
                                                  * (phis[1] - phis[0]))])


def ellipse_points(n: int, a: float, b: float, step: float, start: float = 0.0,
                   tangent: bool = True) -> Iterator[Point]:
    """Counter-clockwise round the ellipse from parameter `start`, `step` m apart along it.

    theta is the tangent's angle (what the camera measures), or with tangent False the
    parameter plus pi/2: the circle's relation, which the conic model assumes.
    """
    phis, arc = ellipse_arc(a, b)
    s0 = float(np.interp(start % (2 * math.pi), phis, arc))
    for k in range(n):
        s = k * step
        phi = float(np.interp((s0 + s) % arc[-1], arc, phis))
        x, y = a * math.cos(phi), b * math.sin(phi)
        theta = math.atan2(b * math.cos(phi), -a * math.sin(phi)) if tangent else phi + math.pi / 2
        yield Point(x, y, theta, s)


# -- I2: the polynomial profile -------------------------------------------------------------------

def printed_polynomial(points: list[Point]) -> tuple[float, ...]:
    """(a0 .. b2) by the thesis's printed closed form: slopes from raw sums, then the intercept.

    a1, a2 solve the 2 x 2 normal equations of x on (s, s^2) without the constant, and a0 =
    (sum x - a1 sum s - a2 sum s^2) / n (5.4.2, the forms after Eq. 5.44 and 5.54); likewise b.
    """
    s = np.array([p.s for p in points])
    s1, s2, s3, s4 = (float(np.sum(s ** k)) for k in (1, 2, 3, 4))
    out = []
    for z in (np.array([p.x for p in points]), np.array([p.y for p in points])):
        z1, z2 = float(z @ s), float(z @ (s * s))
        det = s2 * s4 - s3 * s3
        c1, c2 = (z1 * s4 - s3 * z2) / det, (z2 * s2 - s3 * z1) / det
        out += [(float(z.sum()) - c1 * s1 - c2 * s2) / len(s), c1, c2]
    return tuple(out)


def i2_run(n: int, rng: np.random.Generator | None) -> list[np.ndarray | None]:
    """Relative error of each coefficient after each sample."""
    fit, out = PolynomialFit(), []
    for point in i2_points(n):
        q = across(point, rng)
        fit.add(q.x, q.y, q.s)
        k = fit.coefficients
        out.append(None if k is None else np.abs(np.subtract(k, I2)) / np.abs(I2))
    return out


def i2(seeds: int) -> dict:
    exact = i2_run(400, None)
    noisy = [i2_run(400, np.random.default_rng(seed)) for seed in range(seeds)]
    printed = np.abs(np.subtract(printed_polynomial(list(i2_points(400))), I2)) / np.abs(I2)
    worst = lambda run: [None if e is None else float(e.max()) for e in run]  # noqa: E731
    return {'exact200': exact[199], 'exact400': exact[399], 'printed400': printed,
            'noisy400': np.median([run[399] for run in noisy], axis=0),
            'converged': settle(worst(exact)),
            'converged_noisy': median([settle(worst(run)) for run in noisy])}


# -- I3, I6, I7: the straight line ----------------------------------------------------------------

def line_run(speed: float, dt: float, rng: np.random.Generator | None) -> dict:
    """Slope errors of y = m x + c (plain) and of the polynomial's tangent, sample by sample."""
    line, poly = LineFit(form='plain'), PolynomialFit()
    # All the data since the start, as the thesis fitted (route following's default is a
    # sliding window, for routes of several shapes).
    fitter = TrackFitter(IdentificationParams(model='line', line_form='plain',
                                             memory='all'))
    line_err, poly_err, switched = [], [], None
    for k, point in enumerate(line_points(speed, dt)):
        q = across(point, rng)
        line.add(q.x, q.y, q.s)
        poly.add(q.x, q.y, q.s)
        fitter.add(q.x, q.y, q.theta, q.s)
        if switched is None and fitter.model == 'line':
            switched = (k + 1, q.s)
        m = line.slope_intercept
        line_err.append(None if m is None else abs(m[0] / I3_SLOPE - 1.0))
        d = poly.derivatives(q.s)
        poly_err.append(None if d is None else abs(d[1] / d[0] / I3_SLOPE - 1.0))
    first = round(1.5 / (speed * dt))  # samples in the first 1.5 m
    return {'line': settle(line_err), 'poly': settle(poly_err), 'switched': switched,
            'line_early': max(e for e in line_err[:first] if e is not None),
            'poly_early': max(e for e in poly_err[:first] if e is not None)}


def lines(speed: float, dt: float, seeds: int) -> dict:
    exact = line_run(speed, dt, None)
    noisy = [line_run(speed, dt, np.random.default_rng(seed)) for seed in range(seeds)]
    out = {f'{key}_exact': exact[key] for key in ('line', 'poly', 'switched')}
    for key in ('line', 'poly', 'line_early', 'poly_early'):
        out[f'{key}_noisy'] = median([run[key] for run in noisy])
    return out


# -- I4, I5: the conic model ----------------------------------------------------------------------

def i4(seeds: int) -> dict:
    """Centre offset (m), radius (m) and its error after 400 and 600 samples."""
    def run(rng: np.random.Generator | None) -> dict:
        fit, radius_err, out = ConicFit(), [], {}
        for k, point in enumerate(circle_points(600)):
            q = across(point, rng)
            fit.add(q.x, q.y, q.theta, q.s)
            c = fit.circle()
            radius_err.append(None if c is None else abs(c[2] / 3.0 - 1.0))
            if k + 1 in (400, 600):
                out[k + 1] = (math.hypot(c[0], c[1]), c[2], abs(c[2] / 3.0 - 1.0))
        out['converged'] = settle(radius_err)
        return out

    exact = run(None)
    noisy = [run(np.random.default_rng(seed)) for seed in range(seeds)]
    out = {'exact': exact, 'noisy': {'converged': median([r['converged'] for r in noisy])}}
    for n in (400, 600):
        out['noisy'][n] = tuple(median([r[n][j] for r in noisy]) for j in range(3))
    return out


def ellipse_errors(points: Iterator[Point], a: float, b: float, at: Sequence[int]
                   ) -> dict[int, tuple[float, float, float]]:
    """(semi-major error, semi-minor error, centre offset m) of the conic fit after `at`."""
    fit, out = ConicFit(), {}
    for k, p in enumerate(points):
        fit.add(p.x, p.y, p.theta, p.s)
        if k + 1 in at:
            cx, cy, major, minor, _ = fit.ellipse()
            out[k + 1] = (major / a - 1.0, minor / b - 1.0, math.hypot(cx, cy))
    return out


def i5() -> dict:
    """Semi-axes 1.5 and 0.75 (7.5.1.5) from the end of the major axis, at V every DT."""
    at = (400, 800)
    return {'tangent': ellipse_errors(ellipse_points(800, 1.5, 0.75, V * DT), 1.5, 0.75, at),
            'parameter': ellipse_errors(ellipse_points(800, 1.5, 0.75, V * DT, tangent=False),
                                        1.5, 0.75, at)}
