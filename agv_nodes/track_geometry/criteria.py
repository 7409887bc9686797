"""Driving criteria: the camera offsets a truck should read on a curve (Rajagopalan 1991, 5.4.3).

A driving criterion says which points of the truck must lie on the track (5.4.3, Figs.
5.7a-e). On a circle of radius R every criterion the thesis lists is met in steady motion by a
truck whose axle centre O runs on a concentric circle of radius rho, heading along it (a
differential drive turning about the circle's centre). Body frame: x forward, y left, O at the
origin; centre on the left (side +1) at (0, rho), on the right (side -1) at (0, -rho). A body
point (x, y) then lies on the track when x^2 + (rho - side y)^2 = R^2.

The camera window centre B is at (L_c, 0). eps_d is the lateral offset, along y, from B to the
track where the line through B across the window meets it; eps_theta the angle of the track's
tangent there from the body axis, counter-clockwise positive (Rajagopalan 1991, 5.2; the
package's camera convention). That point is (L_c, side (rho - sqrt(R^2 - L_c^2))) and the
radius to it makes the angle asin(L_c / R) with the lateral, whatever rho, so

    eps_dd     = side (rho - sqrt(R^2 - L_c^2))
    eps_thetad = side asin(L_c / R)

The criteria differ only in rho:

    window   (Fig. 5.7a) B on the track:              rho = sqrt(R^2 - L_c^2),  eps_dd = 0
    centre   (Fig. 5.7b) O on the track:              rho = R
    casters  (Fig. 5.7c) both caster contacts, at (+-L_a, 0), on the track:
                                                      rho = sqrt(R^2 - L_a^2)
    cameras  (Fig. 5.7d) both window centres, at (+-L_c, 0): as window on a circle (they differ
             only where the curvature changes along the truck)
    area     (Fig. 5.7e) least area between the track and the axis segment -l <= x <= l

casters is the criterion the thesis works out (5.4.4, 5.4.4.3) and the default; its eps_dd is
positive (the tape left of the window centre on a left curve) when L_c > L_a. Rajagopalan
1991, 7.5.2.5 gives eps_dd = 0.055 m, eps_thetad = 0.22 rad on R = 2.95 m, which this gives for
L_c = 0.644 m, L_a = 0.308 m.

The caster contacts are taken at +-L_a on the axis, where they are at zero caster angle (L_a's
definition, Eq. 5.11), as the thesis's numbers of 7.5.2.5 imply. A trailing caster swivels so
that its contact runs sqrt(rho^2 + x_p^2 - s^2) from the centre of the turn
(pivot at x_p, trail s): with the pivots at L_a + s and -(L_a - s) the front contact runs about
L_a s / R outside and the rear as far inside the circle (5 mm on the thesis's circle).
rho^2 + L_a^2 = R^2 sets the mean of their squared radii to R^2, so it splits that error evenly.

Area criterion, derived here (the thesis draws it, Fig. 5.7e, but gives no formula). The axis
segment from -l to l (default l = L_c: the windows are at the truck's ends) and the track
across it, y_t(x) = side (rho - sqrt(R^2 - x^2)), enclose A(rho) = integral |y_t(x)| dx. Where
|x| < x0 = sqrt(R^2 - rho^2) the track lies outside the axis, |y_t| = sqrt(R^2 - x^2) - rho,
which shrinks as rho grows; beyond, it lies inside, |y_t| = rho - sqrt(R^2 - x^2), which grows.
So dA/drho = 2 (l - x0) - 2 x0, zero at x0 = l / 2:

    rho = sqrt(R^2 - l^2 / 4)

The track crosses the axis at x = +-l/2: the chord of the circle along the axis is half the
segment. (Least squares of the gap, or zero net signed area, give instead rho = (1 / 2l) x
integral sqrt(R^2 - x^2) dx = R - l^2 / (6 R) + ..., about l^2 / 24 R nearer the centre.)

Eq. 5.86-5.88 as printed contain no dimension of the truck, and with theta_p the track's
tangent they give eps_thetad = 0 or pi on any circle (Fig. 5.9, which would define theta_p, is
not legible). `printed_offsets` evaluates them for the record: with theta_p read as the truck's
heading they give (0, asin(L_c / R)) on a left-hand circle, the window criterion, never the
casters'. The geometric forms above are what the package uses.
"""

from __future__ import annotations

import math

from agv_nodes.track_geometry.osculating import Circle

CRITERIA = ('window', 'centre', 'casters', 'cameras', 'area')
CAMERA_AHEAD = 0.64  # m, L_c of the CONCIC-II (route_following TurningParams.camera_ahead)
CASTER_DISTANCE = 0.31  # m, L_a (route_following SteeringParams.caster_distance)


def _root(square: float) -> float:
    """Return sqrt(square), 0 if negative: a curve too tight for the point puts O at its centre."""
    return math.sqrt(max(square, 0.0))


def path_radius(radius: float, criterion: str = 'casters', *,
                camera_ahead: float = CAMERA_AHEAD, caster_distance: float = CASTER_DISTANCE,
                half_length: float = 0.0) -> float:
    """Radius rho of the circle the axle centre O runs on under `criterion` (see module doc).

    `radius` is the track's radius R (inf: straight, rho inf). `half_length` is the area
    criterion's l (0: camera_ahead).
    """
    if criterion not in CRITERIA:
        raise ValueError(f'unknown driving criterion {criterion!r}; one of {CRITERIA}')
    if not math.isfinite(radius):
        return math.inf
    r2 = radius * radius
    if criterion in ('window', 'cameras'):
        return _root(r2 - camera_ahead * camera_ahead)
    if criterion == 'centre':
        return radius
    if criterion == 'casters':
        return _root(r2 - caster_distance * caster_distance)
    half = half_length or camera_ahead
    return _root(r2 - 0.25 * half * half)


def desired_offsets(radius: float, side: int = 1, criterion: str = 'casters', *,
                    camera_ahead: float = CAMERA_AHEAD, caster_distance: float = CASTER_DISTANCE,
                    half_length: float = 0.0) -> tuple[float, float]:
    """(eps_dd, eps_thetad) for steady motion on a circle of `radius` under `criterion`.

    `side` is +1 with the centre on the left of the truck, -1 on the right. A straight track
    (radius inf, or side 0) gives (0, 0). camera_ahead may be negative for a rear window: the
    offsets are then those it reads in the body frame (eps_thetad of the opposite sign).
    """
    rho = path_radius(radius, criterion, camera_ahead=camera_ahead,
                      caster_distance=caster_distance, half_length=half_length)
    if not math.isfinite(rho) or side == 0:
        return 0.0, 0.0
    sign = 1.0 if side > 0 else -1.0
    eps_d = rho - _root(radius * radius - camera_ahead * camera_ahead)
    eps_theta = math.asin(max(-1.0, min(1.0, camera_ahead / radius)))
    return sign * eps_d, sign * eps_theta


def centre_side(h: float, k: float, x: float, y: float, heading: float) -> int:
    """+1 when (h, k) lies left of the line through (x, y) along `heading`, -1 right, 0 on it.

    0 also for a centre that is not finite (a straight track).
    """
    cross = math.cos(heading) * (k - y) - math.sin(heading) * (h - x)
    if not math.isfinite(cross) or cross == 0.0:
        return 0
    return 1 if cross > 0.0 else -1


def desired_from_circle(circle: Circle, x: float, y: float, heading: float,
                        criterion: str = 'casters', *, camera_ahead: float = CAMERA_AHEAD,
                        caster_distance: float = CASTER_DISTANCE,
                        half_length: float = 0.0) -> tuple[float, float]:
    """(eps_dd, eps_thetad) for the osculating `circle`, the truck's O at (x, y) on `heading`.

    The osculating circle's radius stands for R (Rajagopalan 1991, 5.4.4.1) and the side of its
    centre relative to the truck sets the signs; a straight track gives (0, 0).
    """
    if circle.straight:
        return 0.0, 0.0
    side = centre_side(circle.h, circle.k, x, y, heading)
    return desired_offsets(circle.radius, side, criterion, camera_ahead=camera_ahead,
                           caster_distance=caster_distance, half_length=half_length)


def printed_offsets(a: float, b: float, h: float, k: float, radius: float,
                    theta_p: float) -> tuple[float, float]:
    """Eq. 5.86-5.88 as printed: (eps_dd, eps_thetad) from (a, b), (h, k), R_1 and theta_p.

        eps        = atan((b - k) / (a - h))          (5.86; taken with atan2 for the quadrant)
        eps_thetad = pi/2 - theta_p + eps              (5.87; wrapped to (-pi, pi])
        eps_dd     = R_1 sin(theta_p - eps) - R_1 cos(eps_thetad)          (5.88)

    Kept to show the defect (see module doc); the package uses desired_offsets.
    """
    eps = math.atan2(b - k, a - h)
    eps_theta = math.remainder(math.pi / 2.0 - theta_p + eps, 2.0 * math.pi)
    eps_d = radius * math.sin(theta_p - eps) - radius * math.cos(eps_theta)
    return eps_d, eps_theta
