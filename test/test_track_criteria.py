"""Driving criteria and the osculating circle (Rajagopalan 1991, 5.4.3-5.4.4, Eq. 5.63-5.88)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import astuple
import math

import pytest

from agv_nodes.track_geometry.criteria import (
    CRITERIA,
    centre_side,
    desired_from_circle,
    desired_offsets,
    path_radius,
    printed_offsets,
)
from agv_nodes.track_geometry.feed_forward import effective_wheelbase, feed_forward_angle
from agv_nodes.track_geometry.osculating import (
    Circle,
    osculating_explicit,
    osculating_implicit,
    osculating_parametric,
)
from agv_nodes.track_geometry.settings import FeedForwardParams

R = 2.95  # m, the thesis's experimental circle (7.5.2.5)
L_C, L_A, TRAIL = 0.64, 0.31, 0.05  # m, the package's CONCIC-II geometry
DT = 0.05


def camera_offsets(x: float, y: float, heading: float, cx: float, cy: float, radius: float,
                   ahead: float) -> tuple[float, float]:
    """Return what a window centred `ahead` of O reads from a circular tape: ground truth.

    eps_d: along the body's y axis from the window centre to the nearer crossing of the tape;
    eps_theta: the tape's tangent there from the body axis, wrapped to (-pi/2, pi/2].
    """
    bx, by = x + ahead * math.cos(heading), y + ahead * math.sin(heading)
    nx, ny = -math.sin(heading), math.cos(heading)
    dx, dy = bx - cx, by - cy
    half = nx * dx + ny * dy
    root = math.sqrt(half * half - (dx * dx + dy * dy - radius * radius))
    t = min(-half + root, -half - root, key=abs)
    qx, qy = dx + t * nx, dy + t * ny
    tangent = math.atan2(qx, -qy)  # counter-clockwise along the circle
    return t, math.remainder(tangent - heading, math.pi)


def body_point(x: float, y: float, heading: float, bx: float, by: float) -> tuple[float, float]:
    c, s = math.cos(heading), math.sin(heading)
    return x + c * bx - s * by, y + s * bx + c * by


def steady_pose(rho: float, side: int, angle: float = 0.3) -> tuple[float, float, float]:
    """Place O on the circle of radius rho about the origin, heading along it (side +1: CCW)."""
    return rho * math.cos(angle), rho * math.sin(angle), angle + side * math.pi / 2.0


def drive(pose: tuple[float, float, float], v: float, theta_s: float, t: float
          ) -> tuple[float, float, float]:
    """Drive a kinematic CONCIC-II at caster angle theta_s for t s (Eq. 5.10-5.11, exact arcs)."""
    x, y, h = pose
    w = v * math.tan(theta_s) / effective_wheelbase(theta_s, L_A, TRAIL)
    for _ in range(round(t / DT)):
        x += v / w * (math.sin(h + w * DT) - math.sin(h))
        y -= v / w * (math.cos(h + w * DT) - math.cos(h))
        h += w * DT
    return x, y, h


# -- E6 and the closed forms --------------------------------------------------------------------

def test_e6_thesis_values_on_its_circle() -> None:
    """7.5.2.5: 0.055 m and 0.22 rad on R = 2.95 m with L_c = 0.644 m, L_a = 0.308 m."""
    eps_d, eps_theta = desired_offsets(R, 1, 'casters', camera_ahead=0.644,
                                       caster_distance=0.308)
    assert round(eps_d, 3) == 0.055
    assert round(eps_theta, 2) == 0.22
    # The package's rounded geometry reads 1.1 mm and 1.4 mrad less.
    eps_d, eps_theta = desired_offsets(R, 1, 'casters', camera_ahead=L_C, caster_distance=L_A)
    assert eps_d == pytest.approx(0.05392, abs=1e-5)
    assert eps_theta == pytest.approx(0.21869, abs=1e-5)
    assert round(eps_d, 3) != 0.055


def test_closed_forms() -> None:
    root_c = math.sqrt(R * R - L_C * L_C)
    assert desired_offsets(R, 1, 'casters') == pytest.approx(
        (math.sqrt(R * R - L_A * L_A) - root_c, math.asin(L_C / R)), abs=1e-15)
    assert desired_offsets(R, 1, 'window') == pytest.approx((0.0, math.asin(L_C / R)))
    assert desired_offsets(R, 1, 'cameras') == desired_offsets(R, 1, 'window')
    assert desired_offsets(R, 1, 'centre')[0] == pytest.approx(R - root_c)
    assert desired_offsets(R, -1, 'casters') == tuple(-e for e in desired_offsets(R, 1))


@pytest.mark.parametrize('criterion', CRITERIA)
def test_straight_track_wants_no_offset(criterion: str) -> None:
    assert desired_offsets(math.inf, 1, criterion) == (0.0, 0.0)
    assert desired_offsets(R, 0, criterion) == (0.0, 0.0)
    assert desired_from_circle(osculating_implicit((0, 0, 0, 0.5, -1.0, 0.3), 1.0, 0.8),
                               0.0, 0.0, 0.0, criterion) == (0.0, 0.0)


def test_unknown_criterion_raises() -> None:
    with pytest.raises(ValueError):
        path_radius(R, 'wheels')


# -- each criterion on a truck in steady motion on the circle ------------------------------------

def named_points(criterion: str) -> list[tuple[float, float]]:
    return {'window': [(L_C, 0.0)], 'centre': [(0.0, 0.0)],
            'casters': [(L_A, 0.0), (-L_A, 0.0)], 'cameras': [(L_C, 0.0), (-L_C, 0.0)],
            'area': [(L_C / 2.0, 0.0), (-L_C / 2.0, 0.0)]}[criterion]


@pytest.mark.parametrize('side', [1, -1])
@pytest.mark.parametrize('criterion', CRITERIA)
def test_criterion_points_stay_on_the_circle(criterion: str, side: int) -> None:
    """The named points of each criterion lie on the track while the truck runs steadily.

    The truck starts with O at the criterion's radius, heading along the circle, and holds the
    feed-forward caster angle for 5 s at 0.6 m/s; the window then reads the desired offsets.
    (For area the points are where the track crosses the axis, +-l/2.)
    """
    rho = path_radius(R, criterion)
    theta = feed_forward_angle(R, side, FeedForwardParams(criterion=criterion))
    pose = drive(steady_pose(rho, side), 0.6, theta, 5.0)
    for bx, by in named_points(criterion):
        assert math.hypot(*body_point(*pose, bx, by)) == pytest.approx(R, abs=1e-9)
    assert math.hypot(pose[0], pose[1]) == pytest.approx(rho, abs=1e-9)
    assert centre_side(0.0, 0.0, *pose) == side
    measured = camera_offsets(*pose, 0.0, 0.0, R, L_C)
    assert measured == pytest.approx(desired_offsets(R, side, criterion), abs=1e-9)
    if criterion == 'cameras':  # the rear window reads the mirror image
        rear = camera_offsets(*pose, 0.0, 0.0, R, -L_C)
        assert rear == pytest.approx(desired_offsets(R, side, camera_ahead=-L_C,
                                                     criterion='cameras'), abs=1e-9)
        assert rear[0] == pytest.approx(0.0, abs=1e-9)
        assert rear[1] == pytest.approx(-measured[1], abs=1e-9)


def gap_area(rho: float, half: float, n: int = 20000) -> float:
    """Return the area between the axis -half..half and the circle R about (0, rho) (midpoints)."""
    h = 2.0 * half / n
    return sum(abs(rho - math.sqrt(R * R - (-half + (i + 0.5) * h) ** 2)) for i in range(n)) * h


@pytest.mark.parametrize('half', [L_C, 0.5])
def test_area_criterion_minimises_the_area(half: float) -> None:
    rho = path_radius(R, 'area', half_length=half)
    best = gap_area(rho, half)
    for step in (-2e-3, -5e-4, 5e-4, 2e-3):
        assert gap_area(rho + step, half) > best
    # zero net area (least squares of the gap) and the point criteria are other radii
    net = (half * math.sqrt(R * R - half * half) + R * R * math.asin(half / R)) / (2.0 * half)
    assert gap_area(net, half) > best + 1e-6
    for other in ('centre', 'window', 'casters'):
        assert gap_area(path_radius(R, other), half) > best + 1e-5


def test_caster_swivel_splits_evenly() -> None:
    """Trailing casters (pivots at L_a + s and -(L_a - s)) run +-L_a s / R off the circle."""
    rho = path_radius(R, 'casters')
    front = math.sqrt(rho ** 2 + (L_A + TRAIL) ** 2 - TRAIL ** 2) - R
    rear = math.sqrt(rho ** 2 + (L_A - TRAIL) ** 2 - TRAIL ** 2) - R
    assert front == pytest.approx(L_A * TRAIL / R, rel=0.01)  # 5.3 mm outside
    assert rear == pytest.approx(-L_A * TRAIL / R, rel=0.01)  # 5.3 mm inside


def test_centre_side() -> None:
    assert centre_side(0.0, 5.0, 0.0, 0.0, 0.0) == 1
    assert centre_side(0.0, -5.0, 0.0, 0.0, 0.0) == -1
    assert centre_side(-5.0, 0.0, 0.0, 0.0, math.pi / 2.0) == 1
    assert centre_side(math.nan, math.nan, 0.0, 0.0, 0.0) == 0


@pytest.mark.parametrize('side', [1, -1])
def test_desired_from_the_osculating_circle(side: int) -> None:
    """The pipeline: the tape's conic, its circle where the window looks, the offsets."""
    cx, cy = 1.0, -2.0
    conic = (1.0, 0.0, 1.0, -2.0 * cx, -2.0 * cy, cx * cx + cy * cy - R * R)
    rho = path_radius(R, 'casters')
    x, y, h = steady_pose(rho, side)
    x, y = x + cx, y + cy
    eps_d, _ = camera_offsets(x, y, h, cx, cy, R, L_C)
    px, py = body_point(x, y, h, L_C, eps_d)
    circle = osculating_implicit(conic, px, py, heading=h)
    assert (circle.h, circle.k, circle.radius) == pytest.approx((cx, cy, R), abs=1e-12)
    assert desired_from_circle(circle, x, y, h) == pytest.approx(desired_offsets(R, side),
                                                                 abs=1e-12)


def test_printed_eq_5_86_to_5_88_degenerate() -> None:
    """With theta_p the tangent they give 0 or pi; with the heading, the window criterion."""
    rho = path_radius(R, 'casters')
    x, y, h = steady_pose(rho, 1)
    eps_d, eps_theta = camera_offsets(x, y, h, 0.0, 0.0, R, L_C)
    a, b = body_point(x, y, h, L_C, eps_d)
    tangent = h + eps_theta
    _, printed_theta = printed_offsets(a, b, 0.0, 0.0, R, tangent)
    assert min(abs(printed_theta), abs(abs(printed_theta) - math.pi)) < 1e-12
    printed = printed_offsets(a, b, 0.0, 0.0, R, h)
    assert printed == pytest.approx(desired_offsets(R, 1, 'window'), abs=1e-12)
    assert abs(printed[0] - desired_offsets(R, 1, 'casters')[0]) > 0.05


# -- osculating circle -------------------------------------------------------------------------

def contact_order(curve: Callable[[float], tuple[float, float]], t: float, circle: Circle,
                  delta: float = 0.02) -> float:
    """Return how fast the curve leaves the circle near t: ~8 at third-order contact, ~4 second."""
    def gap(d: float) -> float:
        return max(abs(math.hypot(px - circle.h, py - circle.k) - circle.radius)
                   for px, py in (curve(t - d), curve(t + d)))
    return gap(delta) / gap(delta / 2.0)


@pytest.mark.parametrize('angle', [0.0, 0.7, math.pi / 2.0, 2.5, math.pi, -1.2])
@pytest.mark.parametrize('ccw', [True, False])
def test_osculating_circle_of_a_circle(angle: float, ccw: bool) -> None:
    """Including the points where f_y = 0 (vertical tangents), where the slope form fails."""
    cx, cy, r = -0.5, 2.0, 1.7
    conic = (1.0, 0.0, 1.0, -2.0 * cx, -2.0 * cy, cx * cx + cy * cy - r * r)
    x, y = cx + r * math.cos(angle), cy + r * math.sin(angle)
    heading = angle + (math.pi / 2.0 if ccw else -math.pi / 2.0)
    c = osculating_implicit(conic, x, y, heading=heading)
    assert (c.h, c.k, c.radius) == pytest.approx((cx, cy, r), abs=1e-12)
    assert c.curvature == pytest.approx(1.0 / r if ccw else -1.0 / r)
    scaled = osculating_implicit(tuple(-3.0 * q for q in conic), x, y, heading=heading)
    assert astuple(scaled) == pytest.approx(astuple(c))  # f and -3 f are the same curve


@pytest.mark.parametrize('t', [0.0, 0.4, 1.0, math.pi / 2.0, 2.2, 3.5, 5.0])
def test_osculating_circle_of_an_ellipse(t: float) -> None:
    """Against the analytic curvature a b / (a^2 sin^2 t + b^2 cos^2 t)^1.5 and the evolute."""
    a, b = 1.5, 0.75  # the thesis's simulated ellipse (7.5.1.5)
    conic = (1.0 / a ** 2, 0.0, 1.0 / b ** 2, 0.0, 0.0, -1.0)
    x, y = a * math.cos(t), b * math.sin(t)
    c = osculating_implicit(conic, x, y, heading=math.atan2(b * math.cos(t), -a * math.sin(t)))
    kappa = a * b / (a * a * math.sin(t) ** 2 + b * b * math.cos(t) ** 2) ** 1.5
    assert c.curvature == pytest.approx(kappa, rel=1e-12)
    evolute = ((a * a - b * b) / a * math.cos(t) ** 3, (b * b - a * a) / b * math.sin(t) ** 3)
    assert (c.h, c.k) == pytest.approx(evolute, abs=1e-12)
    assert contact_order(lambda u: (a * math.cos(u), b * math.sin(u)), t, c) > 7.0


def expand(q: tuple[float, ...], x0: float, y0: float) -> tuple[float, ...]:
    """Return the conic coefficients in (x, y) of a quadratic in u = x - x0, w = y - y0."""
    al, be, ga, de, ep, ph = q
    return (al, be, ga, -2 * al * x0 - be * y0 + de, -2 * ga * y0 - be * x0 + ep,
            al * x0 * x0 + be * x0 * y0 + ga * y0 * y0 - de * x0 - ep * y0 + ph)


@pytest.mark.parametrize('s', [-0.3, 0.1, 0.5, 0.9])
def test_osculating_circle_of_a_parabola(s: float) -> None:
    """The polynomial model of 7.5.1.2: parametric derivatives, its implicit form, contact."""
    a0, a1, a2, b0, b1, b2 = -3.0, -5.0, 5.0, -2.0, -3.0, 1.0
    def curve(u: float) -> tuple[float, float]:
        return a0 + a1 * u + a2 * u * u, b0 + b1 * u + b2 * u * u
    x, y = curve(s)
    c = osculating_parametric(a1 + 2 * a2 * s, b1 + 2 * b2 * s, 2 * a2, 2 * b2, x, y)
    assert contact_order(curve, s, c) > 7.0
    # a2 (b2 u - a2 w)^2 + a1 D1 (b2 u - a2 w) - D1^2 u = 0, D1 = a1 b2 - a2 b1 (Eq. 5.55-5.57)
    d1 = a1 * b2 - a2 * b1
    conic = expand((a2 * b2 * b2, -2 * a2 * a2 * b2, a2 ** 3, a1 * d1 * b2 - d1 * d1,
                    -a1 * d1 * a2, 0.0), a0, b0)
    assert conic[0] * x * x + conic[1] * x * y + conic[2] * y * y + conic[3] * x \
        + conic[4] * y + conic[5] == pytest.approx(0.0, abs=1e-9)
    heading = math.atan2(b1 + 2 * b2 * s, a1 + 2 * a2 * s)
    assert astuple(osculating_implicit(conic, x, y, heading=heading)) == pytest.approx(
        astuple(c), rel=1e-9)


def test_slope_form_and_its_printed_sign() -> None:
    """Eq. 5.72-5.73 with the sign fixed agree with the implicit form; as printed, mirrored."""
    cx, cy, r = 0.3, -0.4, 2.0
    conic = (1.0, 0.0, 1.0, -2.0 * cx, -2.0 * cy, cx * cx + cy * cy - r * r)
    x = cx + 1.1
    y = cy - math.sqrt(r * r - 1.1 ** 2)  # lower half: y(x) concave up, travel +x is CCW
    fx, fy = 2 * (x - cx), 2 * (y - cy)
    slope = -fx / fy
    second = -(2.0 + 2.0 * slope * slope) / fy  # Eq. 5.75 with f_xy = 0
    fixed = osculating_explicit(x, y, slope, second)
    assert astuple(fixed) == pytest.approx(astuple(osculating_implicit(conic, x, y)))
    assert (fixed.h, fixed.k, fixed.radius) == pytest.approx((cx, cy, r))
    printed = osculating_explicit(x, y, slope, second, printed_sign=True)
    assert (printed.h, printed.k) == pytest.approx((2 * x - cx, 2 * y - cy))
    assert centre_side(printed.h, printed.k, x, y, math.atan(slope)) == -1  # the convex side


def test_straight_lines_are_not_errors() -> None:
    for c in (osculating_implicit((0.0, 0.0, 0.0, 1.0, 2.0, -3.0), 1.0, 1.0),
              osculating_parametric(0.3, 0.4, 0.6, 0.8, 1.0, 2.0),  # along the tangent
              osculating_explicit(1.0, 2.0, 0.5, 0.0),
              osculating_parametric(1.0, 0.0, 1e-13, 1e-13, 0.0, 0.0)):
        assert c.straight and c.radius == math.inf and c.curvature == 0.0
        assert math.isnan(c.h) and math.isnan(c.k)
    with pytest.raises(ValueError):
        osculating_implicit((1.0, 0.0, -1.0, 0.0, 0.0, 0.0), 0.0, 0.0)  # crossing of two lines
