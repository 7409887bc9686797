"""Stored trajectories for dead reckoning (Rajagopalan 1991, App. F.9), ROS-free.

App. F.9 drove the CONCIC-II "through a known trajectory without the use of camera vision
feedback", a stored straight line, conic or polynomial, at a cruise speed set before the start.
Here a trajectory is one of route following's `dead_reckoning.trajectories`, written in the
truck's frame at the start of the leg (origin at the axle centre, x along the heading, y to the
left, metres), so one stored trajectory serves wherever the leg begins:

  line                  straight ahead, y = 0
  arc R left|right      the circle of radius R (m) tangent to the heading at the axle
  polynomial a0 a1 a2   y = a0 + a1 x + a2 x^2 (the second order the identification fits)
  conic A B C D E F     A x^2 + B x y + C y^2 + D x + E y + F = 0

Each becomes an implicit conic f = 0 signed so that its tangent (f_y, -f_x) points forwards
where the truck stands (track_guidance.py walks and steers by that convention), and is placed
into the odometry frame by the truck's pose (`place`). A trajectory must pass within START_GAP
of the axle centre: it is the path from where the truck stands. Route following steers along
it by odometry alone with the feed-forward law (track_guidance.TrackGuidance.reckon), as a
window would read it.
"""

from __future__ import annotations

import math

from agv_nodes.track_geometry.fitting import Conic, shift_conic

START_GAP = 0.05  # m: the trajectory must pass this near the axle centre at the leg's start
SHAPES = ('line', 'arc', 'polynomial', 'conic')


def _numbers(words: list[str], count: int, text: str) -> list[float]:
    if len(words) != count:
        raise ValueError(f'{text!r}: {words[0] if words else "a shape"} takes {count - 1} '
                         f'number(s)')
    try:
        values = [float(w) for w in words[1:]]
    except ValueError:
        raise ValueError(f'{text!r}: not a number among {words[1:]}') from None
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f'{text!r}: numbers must be finite')
    return values


def trajectory_conic(text: str) -> Conic:
    """Return the stored trajectory `text` as a conic in the leg-start frame.

    ValueError naming the text and the reason when it is no trajectory.
    """
    words = text.split()
    shape = words[0] if words else ''
    if shape == 'line':
        _numbers(words, 1, text)
        conic: Conic = (0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    elif shape == 'arc':
        if len(words) != 3 or words[2] not in ('left', 'right'):
            raise ValueError(f'{text!r}: an arc is "arc R left" or "arc R right"')
        radius = _numbers(words[:2], 2, text)[0]
        if not radius > 0.0:
            raise ValueError(f'{text!r}: the radius must be > 0')
        k = 1.0 / (2.0 * radius) * (-1.0 if words[2] == 'left' else 1.0)
        conic = (k, 0.0, k, 0.0, 1.0, 0.0)  # x^2 + (y -+ R)^2 = R^2, scaled to |grad f| = 1
    elif shape == 'polynomial':
        a0, a1, a2 = _numbers(words, 4, text)
        conic = (-a2, 0.0, 0.0, -a1, 1.0, -a0)  # f = y - p(x)
    elif shape == 'conic':
        conic = tuple(_numbers(words, 7, text))  # type: ignore[assignment]
    else:
        raise ValueError(f'{text!r}: the shape must be one of {", ".join(SHAPES)}')
    return _signed(conic, text)


def _signed(conic: Conic, text: str) -> Conic:
    """Check the curve passes the axle centre; sign it so that it runs forwards there."""
    A, B, C, D, E, F = conic
    # At the origin f = F and grad f = (D, E): |F| / |grad f| is the distance to the curve to
    # first order, and the gradient gives the sense of travel.
    fx, fy = D, E
    g = math.hypot(fx, fy)
    if not g > 0.0:
        raise ValueError(f'{text!r}: the curve has no direction at the truck')
    gap = abs(F) / g
    if gap > START_GAP:
        raise ValueError(f'{text!r}: passes {gap:.3f} m from the truck (at most {START_GAP})')
    if abs(fy) < 0.1 * g:  # (f_y, -f_x) must point forwards, not across the truck
        raise ValueError(f"{text!r}: the curve crosses the truck's heading at "
                         f'{math.degrees(math.acos(abs(fy) / g)):.0f} deg')
    return (-A, -B, -C, -D, -E, -F) if fy < 0.0 else conic


def place(conic: Conic, x: float, y: float, heading: float) -> Conic:
    """Return the conic of the leg-start frame in the odometry frame, the truck at (x, y, heading).

    With d the point relative to (x, y) and R the rotation by heading, the leg frame's
    coordinates are R^T d: the quadratic form becomes R Q R^T, the linear part R (D, E), and
    shift_conic moves the curve to (x, y).
    """
    A, B, C, D, E, F = conic
    c, s = math.cos(heading), math.sin(heading)
    q11, q12, q22 = A, B / 2.0, C
    # R Q R^T with R = [[c, -s], [s, c]]
    r11 = c * c * q11 - 2.0 * c * s * q12 + s * s * q22
    r22 = s * s * q11 + 2.0 * c * s * q12 + c * c * q22
    r12 = c * s * (q11 - q22) + (c * c - s * s) * q12
    turned = (r11, 2.0 * r12, r22, c * D - s * E, s * D + c * E, F)
    return shift_conic(turned, x, y)
