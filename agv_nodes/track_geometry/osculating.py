"""Osculating ("instantaneously coincident") circle of an identified track curve.

Rajagopalan 1991, 5.4.4.1 (Eq. 5.63-5.85): the steering for the next sample is set from the
circle (X - h)^2 + (Y - k)^2 = R_1^2 that touches the identified track at the extrapolated
point (a, b) and has the same second derivative there. ROS-free.

The thesis works with the slope form. For an implicit curve f(x, y) = 0 (Eq. 5.74-5.75):

    y'  = -f_x / f_y
    y'' = -(f_xx + 2 f_xy y' + f_yy y'^2) / f_y

and the centre and radius (Eq. 5.72, 5.73, 5.63):

    h = a - y' (1 + y'^2) / y''        k = b + (1 + y'^2) / y''        R_1 = (1 + y'^2)^1.5 / |y''|

Eq. 5.72 prints h = a + y' (1 + y'^2) / y''. The slip is in Eq. 5.67, which drops the minus
sign of a circle's y'' = -(1 + y'^2) / (Y - k); carried through Eq. 5.68-5.73 it puts the
centre at the mirror image of the true one through (a, b), on the convex side of the track,
where steering toward it turns the wrong way. `osculating_explicit` keeps the printed sign as
the named option `printed_sign` to show that; everything else uses the corrected centre.

The slope form fails where the tangent is vertical (f_y = 0), which a track in the floor frame
reaches on every curve. `osculating_implicit` therefore uses the same curvature in gradient and
Hessian form, which has no preferred axis:

    kappa = -(f_xx f_y^2 - 2 f_xy f_x f_y + f_yy f_x^2) / (f_x^2 + f_y^2)^1.5

signed for the tangent (f_y, -f_x); it equals y'' / (1 + y'^2)^1.5 wherever f_y > 0, so it is
Eq. 5.74-5.75 and 5.72-5.73 rewritten, not a different circle. For the polynomial in travelled
distance (Eq. 5.53-5.54, 5.81-5.85) the parametric form is simpler still
(`osculating_parametric`).

Signs: the curvature is positive when the curve turns counter-clockwise (to the left) along
its direction of travel, with its centre on the left. A straight line has curvature 0, an
infinite radius and no centre (NaN); no exception is raised for it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

# Below this |curvature| (1/m), a radius beyond 1e9 m, the curve counts as straight: a fitted
# quadratic term of rounding size must not put a centre a light-second away.
MIN_CURVATURE = 1e-9


@dataclass(frozen=True)
class Circle:
    """The osculating circle at one point of a track: centre (h, k), radius, signed curvature.

    curvature > 0: the track turns left along its direction, the centre on its left. A
    straight track: curvature 0, radius inf, centre (nan, nan).
    """

    h: float
    k: float
    radius: float
    curvature: float

    @property
    def straight(self) -> bool:
        """True for a straight line (no finite centre)."""
        return self.curvature == 0.0


STRAIGHT = Circle(math.nan, math.nan, math.inf, 0.0)


def circle_from_tangent(x: float, y: float, tx: float, ty: float, curvature: float,
                        min_curvature: float = MIN_CURVATURE) -> Circle:
    """Return the circle of signed `curvature` through (x, y) with unit tangent (tx, ty).

    The centre lies 1 / curvature along the left normal (-ty, tx).
    """
    if not math.isfinite(curvature) or abs(curvature) <= min_curvature:
        return STRAIGHT
    r = 1.0 / curvature
    return Circle(x - ty * r, y + tx * r, abs(r), curvature)


def osculating_explicit(a: float, b: float, slope: float, second: float, *,
                        printed_sign: bool = False) -> Circle:
    """Eq. 5.72-5.73 for y = f(x) at (a, b) from y' (`slope`) and y'' (`second`), travel +x.

    With `printed_sign` the centre is h = a + y' (1 + y'^2) / y'' as Eq. 5.72 prints it (and
    k from Eq. 5.73 with that h): the mirror image of the true centre through (a, b), kept only
    to show the defect. The curvature is y'' / (1 + y'^2)^1.5 either way.
    """
    if not math.isfinite(second) or second == 0.0:
        return STRAIGHT
    q = 1.0 + slope * slope
    curvature = second / q ** 1.5
    if abs(curvature) <= MIN_CURVATURE:
        return STRAIGHT
    sign = 1.0 if printed_sign else -1.0
    return Circle(a + sign * slope * q / second, b - sign * q / second, q ** 1.5 / abs(second),
                  curvature)


def conic_gradient(coeffs: Sequence[float], x: float, y: float
                   ) -> tuple[float, float, float, float, float]:
    """(f_x, f_y, f_xx, f_xy, f_yy) of A x^2 + B x y + C y^2 + D x + E y + F at (x, y).

    Eq. 5.76-5.80 for the conic of Eq. 5.50, written for the general conic.
    """
    A, B, C, D, E, _ = (float(c) for c in coeffs)
    return 2.0 * A * x + B * y + D, B * x + 2.0 * C * y + E, 2.0 * A, B, 2.0 * C


def osculating_implicit(coeffs: Sequence[float], x: float, y: float,
                        heading: float | None = None) -> Circle:
    """Osculating circle of the conic A x^2 + B x y + C y^2 + D x + E y + F = 0 at (x, y).

    `coeffs` is (A, B, C, D, E, F) and (x, y) a point on the curve (off it, the circle is that
    of the level curve through the point). The curve is oriented along `heading` (rad, the
    direction of travel; the tangent taken is the one within 90 degrees of it) or, with None,
    along increasing x as the thesis's y(x) form is (increasing y where the tangent is
    vertical). A line (A = B = C = 0) or a point where the conic is flat gives STRAIGHT.

    Raises ValueError at a singular point of the conic (zero gradient), where it has no
    tangent.
    """
    fx, fy, fxx, fxy, fyy = conic_gradient(coeffs, x, y)
    g2 = fx * fx + fy * fy
    if g2 == 0.0 or not math.isfinite(g2):
        raise ValueError(f'the conic has no tangent at ({x}, {y}): zero gradient')
    g = math.sqrt(g2)
    tx, ty = fy / g, -fx / g
    if heading is not None:
        flip = tx * math.cos(heading) + ty * math.sin(heading) < 0.0
    else:
        flip = tx < 0.0 or (tx == 0.0 and ty < 0.0)
    if flip:
        tx, ty = -tx, -ty
    n = fxx * fy * fy - 2.0 * fxy * fx * fy + fyy * fx * fx
    curvature = (n if flip else -n) / (g2 * g)
    return circle_from_tangent(x, y, tx, ty, curvature)


def osculating_parametric(x1: float, y1: float, x2: float, y2: float, x: float, y: float
                          ) -> Circle:
    """Osculating circle at (x, y) of a curve (x(s), y(s)) oriented along increasing s.

    (x1, y1) and (x2, y2) are the first and second derivatives with respect to s there. For
    the polynomial model x = a0 + a1 s + a2 s^2, y = b0 + b1 s + b2 s^2 of Eq. 5.53-5.54:
    x1 = a1 + 2 a2 s, y1 = b1 + 2 b2 s, x2 = 2 a2, y2 = 2 b2. The curvature is
    (x1 y2 - y1 x2) / (x1^2 + y1^2)^1.5; a zero second derivative along the tangent gives
    STRAIGHT.

    Raises ValueError where the curve stops (x1 = y1 = 0) and has no tangent.
    """
    v2 = x1 * x1 + y1 * y1
    if v2 == 0.0 or not math.isfinite(v2):
        raise ValueError(f'the curve has no tangent at ({x}, {y}): zero first derivative')
    v = math.sqrt(v2)
    curvature = (x1 * y2 - y1 * x2) / (v2 * v)
    return circle_from_tangent(x, y, x1 / v, y1 / v, curvature)
