"""Path controllability and differential-drive kinematics (Rajagopalan 1991, Ch. 3).

Theorems 3.1-3.5 against det J^ of the thesis's own Jacobian (Eq. 3.36-3.41), the determinant
its decision equations (3.49-3.52) carry, and the floor-plane kinematics; then Eq. 3.63-3.65.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from agv_nodes.track_geometry.controllability import (
    FORMS,
    body_velocity,
    det_j,
    det_j_differential,
    effective_steer_angle,
    effective_wheelbase,
    reduced_jacobian,
    wheel_rates,
)

R_W, L_A = 0.075, 0.31  # m, wheel radius and wheelbase
ANGLES = np.linspace(-math.pi, math.pi, 7201)  # every 0.05 degrees
INCLINED = [math.radians(a) for a in (5.0, 10.0, 20.0)]


def dets(alpha: float, offset: float, form: str, angles: np.ndarray = ANGLES) -> np.ndarray:
    return np.array([det_j(float(t), alpha, offset, form=form) for t in angles])


def sign_changes(values: np.ndarray, angles: np.ndarray = ANGLES) -> list[float]:
    """Return the steering angles (degrees) where det J^ changes sign or touches zero."""
    s = np.sign(np.where(np.abs(values) < 1e-15, 0.0, values))
    at = np.flatnonzero((s[:-1] * s[1:] < 0) | (s[:-1] == 0))
    return [float(np.degrees(angles[i])) for i in at]


# -- Theorem 3.3: vertical column, no offset ---------------------------------------------------

@pytest.mark.parametrize('form', FORMS)
def test_theorem_3_3_singular_at_every_angle(form: str) -> None:
    assert np.max(np.abs(dets(0.0, 0.0, form))) < 1e-15
    # and not because the determinant is small: with an offset it is of order r s / L_a
    assert np.max(np.abs(dets(0.0, 0.05, form))) > 0.9 * R_W * 0.05 / L_A


# -- Theorem 3.1: inclined column, no offset ---------------------------------------------------

@pytest.mark.parametrize('alpha', INCLINED)
def test_theorem_3_1_zeros_at_odd_multiples_of_pi_over_2(alpha: float) -> None:
    """Jacobian as printed: r^2 sin(a) c (sin^2 a + c cos^2 a) / L_ae, zero at +-90 degrees.

    Its second factor adds zeros at cos(theta_s) = -tan^2(alpha), past 90 degrees, which the
    thesis's Eq. 3.50-3.51 miss.
    """
    values = dets(alpha, 0.0, 'jacobian')
    extra = math.degrees(math.acos(-math.tan(alpha) ** 2))
    assert sign_changes(values) == pytest.approx([-extra, -90.0, 90.0, extra], abs=0.06)
    for t in (math.pi / 2.0, -math.pi / 2.0, 3.0 * math.pi / 2.0):
        assert abs(det_j(t, alpha, 0.0)) < 1e-17
    inside = np.abs(ANGLES) < math.radians(89.99)
    assert np.all(values[inside] > 0.0)
    c = np.cos(ANGLES)
    lae = np.array([effective_wheelbase(float(t), alpha, 0.0, R_W, L_A) for t in ANGLES])
    closed = R_W ** 2 * math.sin(alpha) * c * (math.sin(alpha) ** 2 + c * math.cos(alpha) ** 2)
    assert values == pytest.approx(closed / lae, abs=1e-15)


@pytest.mark.parametrize('alpha', INCLINED)
def test_theorem_3_1_not_in_the_plane(alpha: float) -> None:
    """The floor-plane kinematics: r^2 sin(a) sqrt(c^2 + cos^2(a) S^2) / L_ae, never zero."""
    values = dets(alpha, 0.0, 'planar')
    assert sign_changes(values) == []
    assert np.min(values) > 0.9 * R_W ** 2 * math.sin(alpha) * math.cos(alpha) / (2 * L_A)


# -- Theorem 3.2: vertical column with offset --------------------------------------------------

@pytest.mark.parametrize('offset', [0.01, 0.05, 0.1])  # L_ae > 0: s < L_a / 2
def test_theorem_3_2_does_not_follow_from_the_jacobian(offset: float) -> None:
    """Det J^ = -r s / L_ae at every angle: no zero at (2n+1) pi/4."""
    for form in ('jacobian', 'planar'):
        values = dets(0.0, offset, form)
        lae = np.array([effective_wheelbase(float(t), 0.0, offset, R_W, L_A) for t in ANGLES])
        assert values == pytest.approx(-R_W * offset / lae, rel=1e-12)
        assert det_j(math.pi / 4.0, 0.0, offset, form=form) < -0.5 * R_W * offset / L_A


@pytest.mark.parametrize('offset', [0.01, 0.05, 0.1])  # L_ae > 0: s < L_a / 2
def test_theorem_3_2_is_the_decision_equations_sign(offset: float) -> None:
    """With the sign Eq. 3.49-3.52 carry, -r s (2 c^2 - 1) / L_ae: zeros at (2n+1) pi/4."""
    values = dets(0.0, offset, 'decision')
    assert sign_changes(values) == pytest.approx([-135.0, -45.0, 45.0, 135.0], abs=0.06)
    lae = np.array([effective_wheelbase(float(t), 0.0, offset, R_W, L_A) for t in ANGLES])
    assert values == pytest.approx(-R_W * offset * np.cos(2.0 * ANGLES) / lae, abs=1e-15)
    for n in range(4):
        assert abs(det_j((2 * n + 1) * math.pi / 4.0, 0.0, offset, form='decision')) < 1e-16


# -- Theorem 3.4: inclined column with offset --------------------------------------------------

@pytest.mark.parametrize(('alpha_deg', 'offset'), [(5.0, 0.02), (10.0, 0.05), (20.0, 0.05),
                                                    (30.0, 0.1)])
def test_theorem_3_4_never_singular_with_trail(alpha_deg: float, offset: float) -> None:
    """S > r sin(alpha): the Jacobian as printed and the floor-plane one never vanish."""
    alpha = math.radians(alpha_deg)
    assert offset > R_W * math.sin(alpha)
    for form in ('jacobian', 'planar'):
        values = dets(alpha, offset, form)
        assert sign_changes(values) == []
        assert np.min(np.abs(values)) > 1e-4
    # the decision equations' sign crosses zero here, against the theorem
    assert len(sign_changes(dets(alpha, offset, 'decision'))) == 4


def test_theorem_3_4_needs_the_offset_beyond_r_sin_alpha() -> None:
    alpha, offset = math.radians(30.0), 0.02  # r sin(alpha) = 0.0375 m > s
    assert len(sign_changes(dets(alpha, offset, 'jacobian'))) == 4
    # in the plane the only singular column is the one whose axis meets the contact point
    assert sign_changes(dets(alpha, offset, 'planar')) == []
    assert np.max(np.abs(dets(alpha, R_W * math.sin(alpha), 'planar'))) < 1e-17


# -- the Jacobian itself -----------------------------------------------------------------------

@pytest.mark.parametrize('form', ['jacobian', 'planar'])
def test_side_offset_of_the_reference_point_cancels(form: str) -> None:
    for t in (-2.0, -0.4, 0.3, 1.2):
        base = det_j(t, 0.2, 0.05, form=form)
        assert det_j(t, 0.2, 0.05, form=form, lateral=0.3) == pytest.approx(base, rel=1e-12)


def test_closed_form_of_the_printed_jacobian() -> None:
    """d21 d42 - d41 d22 = (r / L_ae)[(r sin a - s) c (sin^2 a + c cos^2 a) - s cos a S sin se K].

    The reduction the module docstring states, from Eq. 3.36-3.41 evaluated term by term.
    """
    for alpha, s, t in [(0.2, 0.05, 0.7), (0.4, 0.01, -2.1), (0.1, 0.1, 1.6)]:
        c, sa, ca = math.cos(t), math.sin(alpha), math.cos(alpha)
        lae = effective_wheelbase(t, alpha, s, R_W, L_A)
        drive = (R_W * sa - s) * c * (sa * sa + c * ca * ca)
        steer = s * ca * math.sin(t) * math.sin(effective_steer_angle(t, alpha)) \
            / (c * sa * sa + ca * ca)
        assert det_j(t, alpha, s) == pytest.approx(R_W * (drive - steer) / lae, rel=1e-12)
        assert det_j(t, alpha, s, form='decision') == pytest.approx(R_W * (drive + steer) / lae,
                                                                    rel=1e-12)


def test_printed_rows_equal_the_plane_for_a_vertical_column() -> None:
    for s, lateral, t in [(0.05, 0.0, 0.4), (0.1, 0.2, -1.1), (0.02, -0.1, 2.5)]:
        printed = reduced_jacobian(t, 0.0, s, lateral=lateral)
        planar = reduced_jacobian(t, 0.0, s, lateral=lateral, form='planar')
        assert np.array(printed) == pytest.approx(np.array(planar), abs=1e-15)


@pytest.mark.parametrize(('alpha', 'offset', 'lateral'), [(0.0, 0.05, 0.0), (0.2, 0.05, 0.1),
                                                          (0.35, 0.0, -0.2)])
def test_planar_rows_against_the_contact_point_moved_numerically(
        alpha: float, offset: float, lateral: float) -> None:
    """Solve the no-side-slip rolling of the contact point (Eq. 3.6-3.7, 3.11) numerically.

    The contact point's velocity over the floor (the body's at that point plus its motion in
    the body as theta_s changes, by finite differences of Eq. 3.6-3.7) must be r omega along
    theta_se; the fixed axle has no side velocity. Thesis frame: x right, y forward.
    """
    def contact(t: float) -> np.ndarray:
        lever = R_W * math.sin(alpha) - offset
        return np.array([lever * math.sin(t) - lateral,
                         L_A + lever * (1.0 - math.cos(t)) * math.cos(alpha)])
    for t in (-1.0, 0.3, 1.3):
        h = 1e-6
        moving = (contact(t + h) - contact(t - h)) / (2.0 * h)  # per unit theta_s'
        xc, yc = contact(t)
        se = effective_steer_angle(t, alpha)
        heading = np.array([-math.sin(se), math.cos(se)])
        columns = []
        for omega, rate in ((1.0, 0.0), (0.0, 1.0)):
            # unknowns (v_ry, theta_r'): body velocity at the contact (-yaw y_c, v + yaw x_c)
            a = np.array([[0.0, -yc], [1.0, xc]])
            columns.append(np.linalg.solve(a, R_W * omega * heading - rate * moving))
        expected = np.array(columns).T  # rows v_ry, theta_r'; columns omega, theta_s'
        got = np.array(reduced_jacobian(t, alpha, offset, lateral=lateral, form='planar'))
        assert got == pytest.approx(expected, abs=1e-8)


def test_unknown_form_raises() -> None:
    with pytest.raises(ValueError):
        det_j(0.1, form='printed')
    with pytest.raises(ValueError):
        reduced_jacobian(0.1, form='decision')


# -- Theorem 3.5 and the differential drive's kinematics ------------------------------------------

@pytest.mark.parametrize(('left', 'right'), [(0.26, 0.26), (0.1, 0.4), (0.5, 0.05)])
def test_theorem_3_5_differential_drive_never_singular(left: float, right: float) -> None:
    det = det_j_differential(wheel_radius=R_W, half_left=left, half_right=right)
    assert det == pytest.approx(R_W ** 2 / (left + right))
    j = np.array([[R_W * right, R_W * left], [-R_W, R_W]]) / (left + right)
    assert np.linalg.det(j) == pytest.approx(det)


@pytest.mark.parametrize(('left', 'right'), [(0.26, 0.26), (0.1, 0.4)])
def test_round_trip(left: float, right: float) -> None:
    rng = np.random.default_rng(1991)
    geometry = dict(wheel_radius=R_W, half_left=left, half_right=right)
    for v, yaw in rng.uniform(-2.0, 2.0, size=(200, 2)):
        w1, w2 = wheel_rates(float(v), float(yaw), **geometry)
        back_v, _, back_yaw = body_velocity(w1, w2, **geometry)
        assert abs(back_v - v) < 1e-9 and abs(back_yaw - yaw) < 1e-9
    for w1, w2 in rng.uniform(-20.0, 20.0, size=(200, 2)):
        v, _, yaw = body_velocity(float(w1), float(w2), **geometry)
        assert np.allclose(wheel_rates(v, yaw, **geometry), (w1, w2), rtol=0.0, atol=1e-9)


def test_signs_and_lever_rule() -> None:
    """A left turn speeds the right wheel; the reference point moves as the lever rule says."""
    w1, w2 = wheel_rates(0.5, 0.4, wheel_radius=R_W)
    assert w2 > w1 and R_W * (w2 - w1) == pytest.approx(0.4 * 0.52)
    left, right = 0.1, 0.4
    v, lateral_speed, yaw = body_velocity(2.0, 6.0, wheel_radius=R_W, half_left=left,
                                          half_right=right, lateral=0.05)
    assert v == pytest.approx(R_W * 2.0 + left * yaw)  # the left rim plus the yaw lever
    assert v == pytest.approx(R_W * 6.0 - right * yaw)
    assert lateral_speed == pytest.approx(0.05 * yaw)


@pytest.mark.parametrize(('left', 'right'), [(0.26, 0.26), (0.1, 0.4)])
def test_printed_inverse_returns_minus_the_wheel_speeds(left: float, right: float) -> None:
    """Eq. 3.65 applied to Eq. 3.64 gives -omega: the determinant's sign is dropped."""
    forward = R_W / (left + right) * np.array([[left, right], [1.0, -1.0]])  # Eq. 3.64
    printed = np.array([[-1.0, -right], [-1.0, left]]) / R_W  # Eq. 3.65
    assert printed @ forward == pytest.approx(-np.eye(2))
