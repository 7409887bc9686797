"""Least-squares identification of the track (Rajagopalan 1991, 5.4.2, 7.5.1.2-7.5.1.5)."""

from __future__ import annotations

from collections.abc import Iterator
import math

import numpy as np
import pytest

from agv_nodes.settings import SettingError, build
from agv_nodes.track_geometry.fitting import (
    ConicFit,
    LineFit,
    PolynomialFit,
    Sample,
    ellipse_of,
)
from agv_nodes.track_geometry.settings import IdentificationParams
from agv_nodes.track_geometry.track_fitter import TrackFitter

V, DT = 0.3, 0.05  # the thesis's simulations (Rajagopalan 1991, 7.5.1)
STEP = V * DT  # m between samples
I2 = (-3.0, -5.0, 5.0, -2.0, -3.0, 1.0)  # a0, a1, a2, b0, b1, b2 (7.5.1.2)
I2_QUOTED = (0.026, 0.01, 0.001, 0.025, 0.01, 0.001)  # its errors after 400 samples
HALF_LAP = round(math.pi * 3.0 / STEP)  # 628 samples on the circle of 3 m (7.5.1.4)


def on_conic(conic: tuple[float, ...], x: float, y: float) -> float:
    """Distance of (x, y) from the conic to first order: |f| / |grad f|, m."""
    A, B, C, D, E, F = conic
    value = A * x * x + B * x * y + C * y * y + D * x + E * y + F
    return abs(value) / math.hypot(2 * A * x + B * y + D, B * x + 2 * C * y + E)


def i2_samples(n: int, noise: float = 0.0, seed: int = 0) -> Iterator[tuple[float, ...]]:
    """(x, y, s) of the thesis's polynomial profile, s = V t."""
    rng = np.random.default_rng(seed)
    a0, a1, a2, b0, b1, b2 = I2
    for k in range(n):
        s = k * STEP
        ex, ey = noise * rng.standard_normal(2)
        yield a0 + a1 * s + a2 * s * s + ex, b0 + b1 * s + b2 * s * s + ey, s


def line_samples(n: int, slope: float, intercept: float, noise: float = 0.0,
                 seed: int = 0) -> Iterator[tuple[float, ...]]:
    """(x, y, theta_p, s) along y = slope x + intercept from x = 0, noise on P."""
    rng = np.random.default_rng(seed)
    heading = math.atan2(slope, 1.0)
    for k in range(n):
        s = k * STEP
        ex, ey = noise * rng.standard_normal(2)
        yield s * math.cos(heading) + ex, intercept + s * math.sin(heading) + ey, heading, s


def circle_samples(n: int, radius: float = 3.0, noise: float = 0.0, angle_noise: float = 0.0,
                   seed: int = 0) -> Iterator[tuple[float, ...]]:
    """(x, y, theta_p, s) counter-clockwise round X^2 + Y^2 = R^2 from (R, 0)."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        s = k * STEP
        phi = s / radius
        ex, ey, et = rng.standard_normal(3) * (noise, noise, angle_noise)
        yield radius * math.cos(phi) + ex, radius * math.sin(phi) + ey, phi + math.pi / 2 + et, s


def ellipse_samples(n: int, a: float, b: float, step: float, start: float = 0.0,
                    tangent: bool = True) -> Iterator[tuple[float, ...]]:
    """(x, y, theta_p, s) counter-clockwise round the ellipse, `step` m apart along it.

    theta_p is the true tangent's angle (what the camera measures), or with tangent=False the
    ellipse's parameter plus pi/2, the circle's relation carried over.
    """
    phis = np.linspace(0.0, 2 * math.pi, 100001)
    speed = np.hypot(a * np.sin(phis), b * np.cos(phis))
    arc = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2 * (phis[1] - phis[0]))])
    for k in range(n):
        s = k * step
        phi = float(np.interp(s % arc[-1], arc, phis)) + start
        x, y = a * math.cos(phi), b * math.sin(phi)
        theta = math.atan2(b * math.cos(phi), -a * math.sin(phi)) if tangent else phi + math.pi / 2
        yield x, y, theta, s


def relative_errors(got: tuple[float, ...], want: tuple[float, ...]) -> np.ndarray:
    return np.abs(np.subtract(got, want)) / np.abs(want)


# -- the polynomial (I2) ---------------------------------------------------------------------

def test_i2_polynomial_noise_free_is_exact_from_three_samples() -> None:
    fit = PolynomialFit()
    for k, (x, y, s) in enumerate(i2_samples(401)):
        fit.add(x, y, s)
        assert (fit.coefficients is None) == (k < 2)
        if k in (2, 50, 400):
            assert relative_errors(fit.coefficients, I2).max() < 1e-9
    assert fit.residual_rms < 1e-6


def test_i2_polynomial_with_noise_within_the_thesis_by_400_samples() -> None:
    """3 mm of noise on P: each coefficient within the thesis's 2.6/1/0.1 % (measured 10x less)."""
    worst = np.zeros(6)
    for seed in range(10):
        fit = PolynomialFit()
        for x, y, s in i2_samples(401, 0.003, seed):
            fit.add(x, y, s)
        worst = np.maximum(worst, relative_errors(fit.coefficients, I2))
        assert fit.residual_rms == pytest.approx(0.003, rel=0.15)
    assert np.all(worst < I2_QUOTED)  # measured 0.027 0.010 0.0013 0.052 0.029 0.013 %
    assert np.all(worst < np.array(I2_QUOTED) / 5)


def test_polynomial_point_and_derivatives() -> None:
    fit = PolynomialFit()
    for x, y, s in i2_samples(100):
        fit.add(x, y, s)
    a0, a1, a2, b0, b1, b2 = I2
    s = 2.0
    assert fit.point(s) == pytest.approx((a0 + a1 * s + a2 * s * s, b0 + b1 * s + b2 * s * s))
    assert fit.derivatives(s) == pytest.approx((a1 + 2 * a2 * s, b1 + 2 * b2 * s, 2 * a2, 2 * b2))


def test_polynomial_implicit_form_vanishes_on_the_fitted_points() -> None:
    for noise in (0.0, 0.003):
        fit = PolynomialFit()
        for x, y, s in i2_samples(401, noise):
            fit.add(x, y, s)
        conic = fit.implicit()
        assert np.linalg.norm(conic) == pytest.approx(1.0)
        assert conic[1] ** 2 - 4 * conic[0] * conic[2] == pytest.approx(0.0, abs=1e-12)  # parabola
        assert max(on_conic(conic, *fit.point(k * STEP)) for k in range(401)) < 1e-9


def test_polynomial_implicit_form_when_a2_vanishes() -> None:
    """Eq. 5.57 is a2 times the curve: here x is linear in s, and the curve must not vanish."""
    fit = PolynomialFit()
    for k in range(50):
        s = k * STEP
        fit.add(1.0 + 2.0 * s, -1.0 + 0.5 * s + 0.7 * s * s, s)
    conic = fit.implicit()
    assert max(abs(c) for c in conic) > 0.1
    for s in (0.0, 0.4, 3.0):
        assert on_conic(conic, 1.0 + 2.0 * s, -1.0 + 0.5 * s + 0.7 * s * s) < 1e-9
    assert on_conic(conic, 1.0, -0.9) > 0.05
    straight = PolynomialFit()
    for x, y, _, s in line_samples(50, 1.333, 2.0):
        straight.add(x, y, s)
    line = straight.implicit()  # a parabola whose quadratic part is rounding
    assert max(abs(c) for c in line[:3]) < 1e-9
    assert on_conic(line, 3.0, 1.333 * 3.0 + 2.0) < 1e-9
    along_x = PolynomialFit()
    for k in range(50):
        along_x.add(k * STEP, 0.0, k * STEP)
    assert along_x.implicit() == pytest.approx((0.0, 0.0, 0.0, 0.0, 1.0, 0.0))  # y = 0


# -- the straight line (I3) ------------------------------------------------------------------

def test_i3_polynomial_for_the_first_1_5_m_then_the_line() -> None:
    fitter = TrackFitter(IdentificationParams(model='line'))
    for k, (x, y, theta, s) in enumerate(line_samples(201, 1.333, 2.0, 0.003, seed=4)):
        fitter.add(x, y, theta, s)
        want = None if k < 2 else 'polynomial' if s < 1.5 - 1e-9 else 'line'
        assert fitter.model == want, k
    slope, intercept = fitter.line.slope_intercept
    assert slope == pytest.approx(1.333, rel=0.005)  # measured within 0.1 % over 10 seeds
    assert intercept == pytest.approx(2.0, abs=0.005)  # within 1.7 mm
    assert fitter.line.heading == pytest.approx(math.atan(1.333), abs=0.005)


def test_i3_line_form_converges_faster_than_the_polynomial() -> None:
    """The median slope error over 20 runs, y = m x + c against the polynomial's tangent."""
    errors: dict[int, list[tuple[float, float]]] = {100: [], 200: []}
    for seed in range(20):
        line, poly = LineFit(form='plain'), PolynomialFit()
        for k, (x, y, _, s) in enumerate(line_samples(201, 1.333, 2.0, 0.003, seed)):
            line.add(x, y, s)
            poly.add(x, y, s)
            if k in errors:
                dx, dy, _, _ = poly.derivatives(s)
                errors[k].append((abs(line.slope_intercept[0] - 1.333), abs(dy / dx - 1.333)))
    for k, pairs in errors.items():
        line_err, poly_err = np.median(pairs, axis=0)
        assert line_err < poly_err / 2, k  # measured about 4x


def test_a_line_along_y() -> None:
    """The thesis's y = m x + c has no solution on it; tls and swap have (6, 'no crash')."""
    points = [(1.0, 0.5 + k * STEP, k * STEP) for k in range(60)]
    fits = {form: LineFit(form=form) for form in LineFit.FORMS}
    for fit in fits.values():
        for x, y, s in points:
            fit.add(x, y, s)
    assert fits['plain'].normal_form is None
    for form in ('tls', 'swap'):
        fit = fits[form]
        assert fit.slope_intercept is None
        assert fit.heading == pytest.approx(math.pi / 2)
        nx, ny, d = fit.normal_form
        assert (abs(nx), ny, d * nx) == pytest.approx((1.0, 0.0, 1.0), abs=1e-12)
        assert on_conic(fit.implicit(), 1.0, 40.0) < 1e-12
        assert fit.residual_rms < 1e-9
    back = LineFit()
    for x, y, s in points:
        back.add(x, -y, s)
    assert back.heading == pytest.approx(-math.pi / 2)


@pytest.mark.parametrize('seed', range(5))
def test_along_y_with_noise_the_plain_form_gives_huge_slopes_of_either_sign(seed: int) -> None:
    """1 mm of noise across a line along y, samples 5 to 60 (the measured worst in comments)."""
    rng = np.random.default_rng(seed)
    plain, tls = LineFit(form='plain'), LineFit(form='tls')
    slopes = []
    for k in range(60):
        x, y = 1.0 + 0.001 * rng.standard_normal(), k * STEP
        plain.add(x, y, k * STEP)
        tls.add(x, y, k * STEP)
        if k >= 4:
            slopes.append(plain.slope_intercept[0])
            assert abs(tls.heading - math.pi / 2) < 0.03  # 0.02
    assert max(abs(m) for m in slopes) > 20.0  # 23 to 91
    assert sum(a * b < 0 for a, b in zip(slopes, slopes[1:], strict=False)) >= 3  # 4 to 15


# -- the conic: circle (I4) and ellipse (I5) -------------------------------------------------

def test_i4_circle_noise_free() -> None:
    fit = ConicFit()
    for x, y, theta, s in circle_samples(HALF_LAP + 1):
        fit.add(x, y, theta, s)
    cx, cy, radius = fit.circle()
    assert (cx, cy, radius) == pytest.approx((0.0, 0.0, 3.0), abs=1e-9)
    assert fit.coefficients == pytest.approx((0.0, 0.0, 3.0, 0.0, -3.0, 0.0), abs=1e-9)
    conic = fit.implicit()
    for x, y, *_ in circle_samples(2 * HALF_LAP):
        assert on_conic(conic, x, y) < 1e-9
    assert ellipse_of(conic)[:4] == pytest.approx((0.0, 0.0, 3.0, 3.0), abs=1e-9)


@pytest.mark.parametrize('noise', [0.003, 0.005])
def test_i4_circle_with_noise_on_p_within_1_percent_by_half_a_lap(noise: float) -> None:
    """The thesis: centre (0.01, 0.01) m and radius 2.995 m after 600 samples (7.5.1.4)."""
    for seed in range(10):
        fit = ConicFit()
        for x, y, theta, s in circle_samples(HALF_LAP + 1, noise=noise, seed=seed):
            fit.add(x, y, theta, s)
        cx, cy, radius = fit.circle()
        assert math.hypot(cx, cy) < 0.01  # measured at most 1.5 mm
        assert radius == pytest.approx(3.0, rel=0.01)  # measured within 0.03 %
        assert fit.residual_rms == pytest.approx(noise, rel=0.15)


def test_circle_with_a_degree_of_angle_noise_too() -> None:
    """Measured: centre within 15 mm and radius within 0.3 % at half a lap."""
    for seed in range(10):
        fit = ConicFit()
        for x, y, theta, s in circle_samples(HALF_LAP + 1, noise=0.003,
                                             angle_noise=math.radians(1.0), seed=seed):
            fit.add(x, y, theta, s)
        cx, cy, radius = fit.circle()
        assert math.hypot(cx, cy) < 0.03
        assert radius == pytest.approx(3.0, rel=0.01)


def test_i5_ellipse_converges_but_the_tangent_model_is_coarse_at_2_to_1() -> None:
    """Semi-axes 1.5 and 0.75 (Rajagopalan 1991, 7.5.1.5): 484 samples a lap at 0.3 m/s.

    With theta_p the true tangent angle, x = a0 + a1 cos + a2 sin cannot hold on a 2:1 ellipse:
    from 400 samples on the axes settle 14-27 % long and 10-18 % short (three starting points),
    beyond the thesis's 3-10 %, which it quoted for its experiments. The check pins that.
    """
    for start in (0.0, math.pi / 4, math.pi / 2):
        fit, found = ConicFit(), []
        for k, (x, y, theta, s) in enumerate(ellipse_samples(801, 1.5, 0.75, STEP, start)):
            fit.add(x, y, theta, s)
            if k >= 400 and k % 50 == 0:
                found.append(fit.ellipse())
        cx, cy, major, minor, _ = np.array(found).T
        assert np.all(np.hypot(cx, cy) < 0.07)
        assert np.all((0.12 < major / 1.5 - 1) & (major / 1.5 - 1 < 0.28))
        assert np.all((-0.20 < minor / 0.75 - 1) & (minor / 0.75 - 1 < -0.08))


def test_ellipse_fed_its_parameter_angle_is_exact() -> None:
    fit = ConicFit()
    for x, y, theta, s in ellipse_samples(401, 1.5, 0.75, STEP, tangent=False):
        fit.add(x, y, theta, s)
    assert fit.ellipse() == pytest.approx((0.0, 0.0, 1.5, 0.75, 0.0), abs=1e-9)


def test_e7_ellipse_within_the_thesis_errors() -> None:
    """Axes 3.40 and 2.76 m at 0.63 m/s (Rajagopalan 1991, 7.5.2.6: 4.4 and 3.3 % off).

    Read as full axes; the ratio, all the tangent model's error depends on, is the same
    read as semi-axes. Measured: 4.0-6.3 % on both axes from 400 samples.
    """
    for start in (0.0, math.pi / 4, math.pi / 2):
        fit = ConicFit()
        for k, (x, y, theta, s) in enumerate(ellipse_samples(801, 1.70, 1.38, 0.63 * DT,
                                                             start)):
            fit.add(x, y, theta, s)
            if k >= 400 and k % 100 == 0:
                _, _, major, minor, _ = fit.ellipse()
                assert abs(major / 1.70 - 1) < 0.07
                assert abs(minor / 1.38 - 1) < 0.07


# -- model choice, memory, conditioning ------------------------------------------------------

def test_auto_picks_the_line_on_a_straight_and_the_conic_on_a_circle() -> None:
    straight, circle = TrackFitter(), TrackFitter()
    for k, sample in enumerate(line_samples(200, 1.333, 2.0, 0.003, seed=1)):
        x, y, theta, s = sample
        straight.add(x, y, theta + math.radians(1.0) * math.sin(7.0 * k), s)
    for sample in circle_samples(200, noise=0.003, seed=1):
        circle.add(*sample)
    assert straight.model == 'line' and circle.model == 'conic'
    assert straight.residual_rms < 0.004 and circle.residual_rms < 0.004
    assert circle.line.residual_rms > 0.05


@pytest.mark.parametrize('turn', [1, -1])
def test_the_fitters_implicit_curve_is_signed_along_the_travel(turn: int) -> None:
    """(f_y, -f_x) points along travel, counter-clockwise or clockwise round, or on a line."""
    for model, samples, tol in (('conic', circle_samples(300), 1e-6),
                                ('line', line_samples(300, -0.5, 1.0), 1e-6),
                                ('polynomial', circle_samples(300), 0.15)):  # a parabola
        fitter = TrackFitter(IdentificationParams(model=model))
        for x, y, theta, s in samples:
            if model != 'line':  # clockwise: the mirror image in the x axis
                y, theta = turn * y, turn * theta
            fitter.add(x, y, theta, s)
        assert fitter.model == model
        A, B, C, D, E, _ = fitter.implicit()
        fx, fy = 2 * A * x + B * y + D, B * x + 2 * C * y + E
        assert abs(math.remainder(math.atan2(-fx, fy) - theta, 2 * math.pi)) < tol


def route(s: float) -> tuple[float, float, float]:
    """Return (x, y, heading) at s on a line of 3 m, then an arc of 2 m radius to the left."""
    if s < 3.0:
        return s, 0.0, 0.0
    phi = (s - 3.0) / 2.0
    return 3.0 + 2.0 * math.sin(phi), 2.0 - 2.0 * math.cos(phi), phi


@pytest.mark.parametrize(('changes', 'model', 'rms_below', 'resets'), [
    ({'memory': 'all'}, 'conic', 1.0, 0),  # all data since the start (the thesis): no one curve
    ({'memory': 'window', 'window': 1.5}, 'conic', 0.003, 0),
    ({'reset_residual': 0.01}, 'conic', 0.003, 1),
])
def test_a_line_then_an_arc(changes: dict, model: str, rms_below: float, resets: int) -> None:
    rng = np.random.default_rng(5)
    fitter = TrackFitter(IdentificationParams(**changes))
    for k in range(500):  # 7.5 m
        x, y, heading = route(k * STEP)
        fitter.add(x + 0.002 * rng.standard_normal(), y + 0.002 * rng.standard_normal(),
                   heading, k * STEP)
    assert fitter.model == model
    assert fitter.residual_rms < rms_below
    assert fitter.resets == resets
    if changes == {'memory': 'all'}:
        assert fitter.residual_rms > 0.3
    if resets:
        assert 7.5 - 4.5 < fitter.travelled < 7.5 - 3.0  # reset soon after the arc began


def test_sliding_window_equals_a_fresh_fit_of_its_samples() -> None:
    """Subtracting leaving samples and re-basing the sums loses nothing."""
    samples = [Sample(s, x, y, theta) for x, y, theta, s in circle_samples(900, noise=0.003)]
    windowed = ConicFit(window=2.0)
    for p in samples:
        windowed.add(p.x, p.y, p.theta, p.s)
    fresh = ConicFit()
    for p in samples:
        if samples[-1].s - p.s <= 2.0:
            fresh.add(p.x, p.y, p.theta, p.s)
    assert windowed.n == fresh.n == 134
    assert windowed.coefficients == pytest.approx(fresh.coefficients, abs=1e-9)
    assert windowed.residual_rms == pytest.approx(fresh.residual_rms, rel=1e-6)


def test_no_answer_until_solvable() -> None:
    poly, line, conic = PolynomialFit(), LineFit(), ConicFit()
    for k in range(2):
        poly.add(k * STEP, 0.0, k * STEP)
    line.add(0.0, 0.0, 0.0)
    for k in range(50):  # a straight: cos and sin of the heading are constants
        conic.add(k * STEP, 0.0, 0.0, k * STEP)
    assert poly.coefficients is line.normal_form is conic.coefficients is None
    assert poly.implicit() is line.implicit() is conic.implicit() is None
    assert poly.residual_rms is conic.residual_rms is None
    assert TrackFitter().model is None


def test_settings_are_checked() -> None:
    assert IdentificationParams().model == 'auto'
    assert IdentificationParams().switch_distance == 1.5
    with pytest.raises(SettingError):
        build(IdentificationParams, {'model': 'spline'})
    with pytest.raises(SettingError):
        build(IdentificationParams, {'left_scale': 2.0})
    with pytest.raises(ValueError, match='form'):
        LineFit(form='vertical')
