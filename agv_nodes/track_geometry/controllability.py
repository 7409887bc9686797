"""Path controllability: the reduced Jacobian of Rajagopalan 1991, Ch. 3, and its determinant.

A vehicle is path controllable (3.2) when a unique set of wheel rates gives any asked-for
forward speed and yaw rate: the reduced Jacobian J^ from the wheel's (omega, theta_s') to the
vehicle's (v_ry, theta_r') must be invertible (Eq. 3.46-3.48):

    det J^ = d21 d42 - d41 d22

Steered and driven wheel (3.3): steering column inclined by alpha fore and aft, offset s
between the steering axis and the wheel axle, wheel radius r, wheelbase L_a from the fixed axle
to the contact point, reference point on the fixed axle (L_b = 0) and L_d to its side. With
c = cos theta_s, S = sin theta_s:

    theta_se = atan(cos(alpha) tan(theta_s))                          (3.11, effective steer)
    L_ae     = L_a + (r sin(alpha) - s)(1 - c) cos(alpha)             (3.12, effective wheelbase)
    K        = 1 / (c sin^2(alpha) + cos^2(alpha))
    d21 = (sin^2(alpha) + c cos^2(alpha)) r + (s S + L_d / K) K r sin(theta_se) / L_ae   (3.36)
    d22 = (s S + L_d / K) K ((r sin(alpha) - s) c / L_ae + cos(alpha)) - L_d cos(alpha) (3.37)
    d41 = r sin(theta_se) / L_ae                                                          (3.40)
    d42 = (r sin(alpha) - s) c / L_ae                                                     (3.41)

theta_se is taken on the branch continuous with theta_s (atan2), so the wheel does not reverse
at 90 degrees as the principal atan would make it. L_d cancels from the determinant, which
reduces to

    det J^ = (r / L_ae) [(r sin(alpha) - s) c (sin^2(alpha) + c cos^2(alpha))
                         - s cos(alpha) S sin(theta_se) K]

`form` chooses what is evaluated:

jacobian  (default) det J^ of Eq. 3.36-3.41 as printed. It gives
          Theorem 3.1 (inclined, s = 0): r^2 sin(alpha) c (sin^2(alpha) + c cos^2(alpha)) /
              L_ae, zero at theta_s = (2n+1) pi/2 as stated, and also at cos(theta_s) =
              -tan^2(alpha) (91.8 degrees for alpha = 10 degrees), a root of the second factor
              that Eq. 3.50-3.51 do not find.
          Theorem 3.2 (vertical, offset s): -r s / L_ae, never zero. The theorem's zeros at
              (2n+1) pi/4 come from Eq. 3.52, s (2 c^2 - 1) = 0, which has -S^2 where the
              Jacobian gives +S^2 (c^2 + S^2 = 1). The theorem does not follow from the
              thesis's own Jacobian.
          Theorem 3.3 (vertical, s = 0): zero at every steering angle, as stated.
          Theorem 3.4 (inclined, offset): never zero when s > r sin(alpha), as on any caster
              of useful trail; with s < r sin(alpha) it changes sign between 0 and 90 degrees.
decision  the same with the sign of the s S sin(theta_se) term reversed: the sign Eq. 3.52's
          s (2 c^2 - 1) needs (Eq. 3.49 itself is only partly legible, and Eq. 3.50's quadratic
          factor follows from neither form). It reproduces Theorems 3.1-3.3 as stated (zeros
          at (2n+1) pi/2, (2n+1) pi/4, everywhere) but then crosses zero with inclination and
          offset whenever s > r sin(alpha), against Theorem 3.4. Kept to show where the
          statements came from.
planar    the floor-plane kinematics of the thesis's own contact point (Eq. 3.6-3.7), effective
          steer angle (3.11) and yaw rate (3.30), the wheel rolling at r omega along
          theta_se without side slip: rows d41, d42 as printed, and
              d21 = r cos(theta_se) - x_c d41,
              d22 = -x_c d42 - (r sin(alpha) - s) S cos(alpha),
          from v_ry = r omega cos(theta_se) - x_c theta_r' - y_c', the contact point at
          x_c = (r sin(alpha) - s) S - L_d, y_c = L_ae.
          Then det J^ = r (r sin(alpha) - s) sqrt(c^2 + cos^2(alpha) S^2) / L_ae: singular
          only where the steering axis meets the floor at the contact point, r sin(alpha) =
          s (Theorem 3.3 is the case alpha = s = 0), and at every steering angle there. It
          agrees with the jacobian form when alpha = 0, which confirms Theorem 3.2's error.

Differential drive (3.5): wheel #1 on the left at L1 from O, #2 on the right at L2, speeds
omega_1, omega_2, yaw counter-clockwise positive (the package's convention). Then

    v = r (L2 omega_1 + L1 omega_2) / (L1 + L2),   theta_r' = r (omega_2 - omega_1) / (L1 + L2),
    v_lat = L_d theta_r'                                                     (Eq. 3.63-3.64)
    omega_1 = (v - L1 theta_r') / r,   omega_2 = (v + L2 theta_r') / r

and det J^ = r^2 / (L1 + L2) is never zero (Theorem 3.5). The thesis counts its yaw the other
way (theta_r' = r (omega_1 - omega_2) / (L1 + L2), Eq. 3.62) and weights omega_1 by L1 in Eq.
3.63-3.64, which agrees with the lever rule only when L1 = L2. Its inverse, Eq. 3.65, omega =
(1 / r) [[-1, -L2], [-1, L1]] (v, theta_r'), is the inverse of Eq. 3.64 with the sign of the
determinant (-(L1 + L2)) dropped: it returns -omega. Both are fixed here.
"""

from __future__ import annotations

import math

FORMS = ('jacobian', 'decision', 'planar')
WHEEL_RADIUS = 0.075  # m, r of the CONCIC-II's drive wheels (150 mm across)
WHEELBASE = 0.31  # m, L_a
HALF_SPAN = 0.26  # m, L1 = L2 = half the CONCIC-II's 0.52 m wheel span


def effective_steer_angle(theta_s: float, alpha: float) -> float:
    """theta_se = atan(cos(alpha) tan(theta_s)) (Eq. 3.11), on the branch through theta_s."""
    return math.atan2(math.cos(alpha) * math.sin(theta_s), math.cos(theta_s))


def effective_wheelbase(theta_s: float, alpha: float, offset: float,
                        wheel_radius: float = WHEEL_RADIUS, wheelbase: float = WHEELBASE
                        ) -> float:
    """L_ae = L_a + (r sin(alpha) - s)(1 - cos(theta_s)) cos(alpha) (Eq. 3.12)."""
    return wheelbase + ((wheel_radius * math.sin(alpha) - offset)
                        * (1.0 - math.cos(theta_s)) * math.cos(alpha))


def reduced_jacobian(theta_s: float, alpha: float = 0.0, offset: float = 0.0, *,
                     wheel_radius: float = WHEEL_RADIUS, wheelbase: float = WHEELBASE,
                     lateral: float = 0.0, form: str = 'jacobian'
                     ) -> tuple[tuple[float, float], tuple[float, float]]:
    """((d21, d22), (d41, d42)): (v_ry, theta_r') from (omega, theta_s'); see module doc.

    form 'jacobian': Eq. 3.36-3.41 as printed; 'planar': the floor-plane rows. `lateral` is L_d.
    """
    if form not in ('jacobian', 'planar'):
        raise ValueError(f"reduced_jacobian form must be 'jacobian' or 'planar', not {form!r}")
    r, s = wheel_radius, offset
    c, S = math.cos(theta_s), math.sin(theta_s)
    sa, ca = math.sin(alpha), math.cos(alpha)
    lever = r * sa - s
    lae = effective_wheelbase(theta_s, alpha, offset, wheel_radius, wheelbase)
    sin_se = math.sin(effective_steer_angle(theta_s, alpha))
    d41 = r * sin_se / lae
    d42 = lever * c / lae
    if form == 'planar':
        x_c = lever * S - lateral
        return (r * math.cos(effective_steer_angle(theta_s, alpha)) - x_c * d41,
                -x_c * d42 - lever * S * ca), (d41, d42)
    k = 1.0 / (c * sa * sa + ca * ca)
    arm = (s * S + lateral * (c * sa * sa + ca * ca)) * k
    d21 = (sa * sa + c * ca * ca) * r + arm * d41
    d22 = arm * (d42 + ca) - lateral * ca
    return (d21, d22), (d41, d42)


def det_j(theta_s: float, alpha: float = 0.0, offset: float = 0.0, *,
          wheel_radius: float = WHEEL_RADIUS, wheelbase: float = WHEELBASE,
          lateral: float = 0.0, form: str = 'jacobian') -> float:
    """Return det J^ of the steered and driven wheel at steering angle theta_s (rad).

    alpha: inclination of the steering column (rad, 0 vertical); offset: s (m, 0 none). form
    'jacobian' (Eq. 3.36-3.41 as printed), 'decision' (the sign Eq. 3.49-3.52 carry) or
    'planar' (the floor-plane kinematics); see the module docstring for what each shows.
    """
    if form not in FORMS:
        raise ValueError(f'unknown form {form!r}; one of {FORMS}')
    if form == 'decision':
        r, s = wheel_radius, offset
        c, S = math.cos(theta_s), math.sin(theta_s)
        sa, ca = math.sin(alpha), math.cos(alpha)
        lae = effective_wheelbase(theta_s, alpha, offset, wheel_radius, wheelbase)
        sin_se = math.sin(effective_steer_angle(theta_s, alpha))
        drive = (r * sa - s) * c * (sa * sa + c * ca * ca)
        steer = s * ca * S * sin_se / (c * sa * sa + ca * ca)
        return r * (drive + steer) / lae
    (d21, d22), (d41, d42) = reduced_jacobian(
        theta_s, alpha, offset, wheel_radius=wheel_radius, wheelbase=wheelbase,
        lateral=lateral, form=form)
    return d21 * d42 - d41 * d22


def det_j_differential(*, wheel_radius: float = WHEEL_RADIUS, half_left: float = HALF_SPAN,
                       half_right: float = HALF_SPAN) -> float:
    """Return det J^ of the differential drive (Eq. 3.64, package signs): r^2 / (L1 + L2)."""
    span = half_left + half_right
    k = wheel_radius / span
    return (k * half_right) * k - (-k) * (k * half_left)


def body_velocity(omega_left: float, omega_right: float, *, wheel_radius: float = WHEEL_RADIUS,
                  half_left: float = HALF_SPAN, half_right: float = HALF_SPAN,
                  lateral: float = 0.0) -> tuple[float, float, float]:
    """(v, v_lat, yaw rate) of the reference point from the wheels' rad/s (Eq. 3.63, fixed).

    The reference point is on the axle half_left from the left wheel (O for equal halves) and
    `lateral` (L_d) to its side; yaw counter-clockwise positive.
    """
    span = half_left + half_right
    yaw_rate = wheel_radius * (omega_right - omega_left) / span
    v = wheel_radius * (half_right * omega_left + half_left * omega_right) / span
    return v, lateral * yaw_rate, yaw_rate


def wheel_rates(v: float, yaw_rate: float, *, wheel_radius: float = WHEEL_RADIUS,
                half_left: float = HALF_SPAN, half_right: float = HALF_SPAN
                ) -> tuple[float, float]:
    """(omega_left, omega_right), rad/s, for forward speed v and yaw rate (Eq. 3.65, fixed)."""
    return ((v - half_left * yaw_rate) / wheel_radius,
            (v + half_right * yaw_rate) / wheel_radius)
