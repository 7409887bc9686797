"""Odometric pose and the track point P (Rajagopalan 1991, 5.4.1, Eq. 5.30-5.39)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agv_nodes.odometry import counter_step
from agv_nodes.track_geometry.pose import RULES, ChordOdometry, PoseIntegrator, track_point

SPAN = 0.52  # m between the drive wheels, as the package's vehicle has it
V, DT = 0.3, 0.05  # the thesis's identification runs (Rajagopalan 1991, 7.5.1)


def wheels(v: float, yaw_rate: float) -> tuple[float, float]:
    """Left and right rim speeds giving forward speed v and a counter-clockwise yaw rate."""
    return v - yaw_rate * SPAN / 2, v + yaw_rate * SPAN / 2


def drive(rule: str, speeds: list[tuple[float, float]], dts: list[float] | None = None,
          **kw: float) -> list[tuple[float, float, float]]:
    """Poses after each sample; the first pair of speeds is the one at the start."""
    pose = PoseIntegrator(SPAN, rule, v_left=speeds[0][0], v_right=speeds[0][1], **kw)
    dts = dts or [DT] * (len(speeds) - 1)
    return [pose.update(left, right, dt) for (left, right), dt in zip(speeds[1:], dts,
                                                                      strict=True)]


# -- closed forms ------------------------------------------------------------------------------

def test_straight_run_is_exact_and_the_printed_simpson_counts_twice() -> None:
    n = 200
    for rule in ('trapezoid', 'simpson'):
        x, y, heading = drive(rule, [(V, V)] * (n + 1))[-1]
        assert x == pytest.approx(V * DT * n, abs=1e-12)
        assert y == heading == 0.0
    # Eq. 5.39 as printed: a trapezoid first step, then dT / 3 (1 + 4 + 1) v = 2 v dT a step.
    x, _, _ = drive('simpson_printed', [(V, V)] * (n + 1))[-1]
    assert x == pytest.approx(V * DT * (2 * n - 1), abs=1e-12)


def test_constant_turn_against_the_circle() -> None:
    """Eq. 5.38 turns each step through the previous heading: the circle lags half a step."""
    radius = 2.0
    rate = V / radius
    n = round(math.pi / 2 * radius / (V * DT))  # a quarter turn
    truth = [(radius * math.sin(rate * k * DT), radius * (1 - math.cos(rate * k * DT)))
             for k in range(1, n + 1)]
    speeds = [wheels(V, rate)] * (n + 1)
    trap = drive('trapezoid', speeds)
    for k, ((x, y, heading), (tx, ty)) in enumerate(zip(trap, truth, strict=True), 1):
        assert heading == pytest.approx(rate * k * DT, abs=1e-12)
        # Eq. 5.38 summed: x(n) = sum over k < n of V dT cos(k w dT), and likewise y.
        angles = rate * DT * np.arange(k)
        assert (x, y) == pytest.approx((V * DT * np.cos(angles).sum(),
                                        V * DT * np.sin(angles).sum()), abs=1e-12)
        # ... which is the true path turned by -w dT / 2 about the start.
        assert math.hypot(x - tx, y - ty) == pytest.approx(
            rate * DT / 2 * math.hypot(tx, ty), abs=1e-6)
    simpson = drive('simpson', speeds)
    assert max(math.hypot(x - tx, y - ty)
               for (x, y, _), (tx, ty) in zip(simpson, truth, strict=True)) < 1e-6


def test_simpson_takes_unequal_sample_periods() -> None:
    """The camera cycle is timed each sample (Rajagopalan 1991, 6.3.4): it is not constant."""
    radius, n = 2.0, 200
    rate = V / radius
    dts = [0.04 if k % 2 else 0.06 for k in range(n)]
    t = sum(dts)
    x, y, heading = drive('simpson', [wheels(V, rate)] * (n + 1), dts)[-1]
    assert heading == pytest.approx(rate * t, abs=1e-12)
    assert math.hypot(x - radius * math.sin(rate * t),
                      y - radius * (1 - math.cos(rate * t))) < 1e-6


# -- the thesis's comparison (I1) and straight-running correction (E2) -------------------------

def test_i1_trapezoid_within_3_mm_and_printed_simpson_worse() -> None:
    """1.5 m of travel over 5 s with a turn and back (Rajagopalan 1991, 7.5.1.1, Fig. 7.17).

    The yaw rate is A sin(2 pi t / T); the true path is integrated finely from the same
    speeds. Lateral error: across the true heading.
    """
    amp, period = 0.2, 1.5 / V
    n = round(period / DT)

    def heading(t: float | np.ndarray) -> float | np.ndarray:
        return amp * period / (2 * math.pi) * (1 - np.cos(2 * np.pi * t / period))

    def truth(t: float) -> tuple[float, float]:
        ts = np.linspace(0.0, t, 4001)  # Simpson over 4000 intervals
        weights = np.ones_like(ts)
        weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
        h = heading(ts)
        step = (ts[1] - ts[0]) / 3
        return step * np.sum(weights * V * np.cos(h)), step * np.sum(weights * V * np.sin(h))

    speeds = [wheels(V, amp * math.sin(2 * math.pi * k * DT / period)) for k in range(n + 1)]
    paths = {rule: drive(rule, speeds) for rule in RULES}
    worst = {}
    for rule, path in paths.items():
        lateral = []
        for k, (x, y, _) in enumerate(path, 1):
            tx, ty = truth(k * DT)
            h = heading(k * DT)
            lateral.append(abs(-math.sin(h) * (x - tx) + math.cos(h) * (y - ty)))
        worst[rule] = max(lateral)
    assert worst['trapezoid'] <= 0.003  # the thesis's 3 mm; measured 2.4 mm
    assert worst['simpson_printed'] > 10 * worst['trapezoid']  # measured 0.68 m
    assert worst['simpson'] < 1e-5


def test_e2_left_wheel_correction_straightens_the_path() -> None:
    """A left wheel read 0.18 % slow bends the odometric path left (Rajagopalan 1991, 7.5.2.2)."""
    n = round(10.0 / (V * DT))  # about 10 m
    read = [(V / 1.0018, V)] * (n + 1)
    x, y, heading = drive('trapezoid', read)[-1]
    rate = V * (1 - 1 / 1.0018) / SPAN
    t = n * DT
    assert heading == pytest.approx(rate * t, rel=1e-3) and heading > 0.0
    assert y == pytest.approx(V * rate * t * t / 2, rel=0.02)  # left, 0.17 m
    x, y, heading = drive('trapezoid', read, left_scale=1.0018)[-1]
    assert abs(y) < 1e-9 and abs(heading) < 1e-12
    assert x == pytest.approx(n * V * DT, abs=1e-9)


# -- inputs ------------------------------------------------------------------------------------

@pytest.mark.parametrize('rule', RULES)
def test_wheel_travel_input_equals_speed_input(rule: str) -> None:
    rng = np.random.default_rng(7)
    speeds = [(V + 0.05 * a, V + 0.05 * b) for a, b in rng.standard_normal((150, 2))]
    dts = list(DT + 0.01 * rng.random(149))
    by_speed = PoseIntegrator(SPAN, rule, 1.001, *speeds[0])
    by_travel = PoseIntegrator(SPAN, rule, 1.001, *speeds[0])
    for (left, right), dt in zip(speeds[1:], dts, strict=True):
        a = by_speed.update(left, right, dt)
        b = by_travel.update_travel(left * dt, right * dt, dt)
        assert b == pytest.approx(a, abs=1e-12)
    assert by_travel.distance == pytest.approx(by_speed.distance, abs=1e-12)


def test_wrapping_mm_counters_feed_the_travel_input() -> None:
    """wheel_odometry's u16 mm counters, wrapping mid-run, give the speeds' pose exactly."""
    left_mm, right_mm = 65500, 65530
    by_speed = PoseIntegrator(SPAN, v_left=0.30, v_right=0.32)
    by_counter = PoseIntegrator(SPAN, v_left=0.30, v_right=0.32)
    for _ in range(100):
        new_left, new_right = (left_mm + 15) % 0x10000, (right_mm + 16) % 0x10000
        a = by_speed.update(0.30, 0.32, DT)
        b = by_counter.update_travel(counter_step(left_mm, new_left) / 1000,
                                     counter_step(right_mm, new_right) / 1000, DT)
        left_mm, right_mm = new_left, new_right
        assert b == pytest.approx(a, abs=1e-12)
    assert by_counter.distance == pytest.approx(100 * 0.031 / 2, abs=1e-12)


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match='rule'):
        PoseIntegrator(SPAN, 'euler')
    with pytest.raises(ValueError, match='wheel_span'):
        PoseIntegrator(0.0)
    with pytest.raises(ValueError, match='period'):
        PoseIntegrator(SPAN).update(V, V, 0.0)


# -- the counters' own heading (ChordOdometry) -------------------------------------------------

def test_chord_odometry_on_a_circle_and_a_straight() -> None:
    """R = 2.95 m (tape_1991) from exact wheel travels: the heading exact, the chords' direction.

    Each step lays the arc's length along the chord's direction, (dpsi / 2) / sin(dpsi / 2)
    times the chord: the path is the true circle scaled by that factor about the start, 6 um
    off it after a half lap, where the trapezoid (Eq. 5.38) lags half a step's turn, 15 mm.
    """
    radius = 2.95
    rate = V / radius
    left, right = wheels(V, rate)
    n = round(math.pi * radius / (V * DT))  # a half lap: 618 steps of 15 mm
    x0, y0, h0 = 1.0, -2.0, 0.4
    centre = (x0 - radius * math.sin(h0), y0 + radius * math.cos(h0))
    chord = ChordOdometry(SPAN, x0, y0, h0)
    trapezoid = PoseIntegrator(SPAN, v_left=left, v_right=right, x=x0, y=y0, heading=h0)
    turn = rate * DT
    scale = (turn / 2) / math.sin(turn / 2)
    worst = 0.0
    for k in range(1, n + 1):
        x, y, heading = chord.update(left * DT, right * DT)
        angle = h0 + k * turn
        assert heading == pytest.approx(angle, abs=1e-12)
        tx, ty = centre[0] + radius * math.sin(angle), centre[1] - radius * math.cos(angle)
        assert (x, y) == pytest.approx((x0 + scale * (tx - x0), y0 + scale * (ty - y0)),
                                       abs=1e-9)
        worst = max(worst, abs(math.hypot(x - centre[0], y - centre[1]) - radius))
    assert chord.pose == (x, y, heading)
    assert 2 * radius * (scale - 1) == pytest.approx(6.4e-6, abs=0.1e-6)
    assert worst <= 2 * radius * (scale - 1) + 1e-9
    for _ in range(n):
        tx, ty, _ = trapezoid.update(left, right, DT)
    lag = math.hypot(tx - x, ty - y)
    assert lag == pytest.approx(turn / 2 * 2 * radius, rel=1e-3)  # 15 mm
    # A straight: exact.
    chord = ChordOdometry(SPAN, x0, y0, h0)
    for k in range(1, 201):
        x, y, heading = chord.update(V * DT, V * DT)
        assert heading == h0
        assert (x, y) == pytest.approx((x0 + k * V * DT * math.cos(h0),
                                        y0 + k * V * DT * math.sin(h0)), abs=1e-12)
    with pytest.raises(ValueError, match='wheel_span'):
        ChordOdometry(0.0)


# -- the track point ---------------------------------------------------------------------------

def test_track_point_signs() -> None:
    """eps_d > 0: tape left of the window's centre; eps_theta > 0: turned counter-clockwise."""
    assert track_point(0.0, 0.0, 0.0, 0.64, 0.02, 0.1) == pytest.approx((0.64, 0.02, 0.1))
    assert track_point(1.0, 1.0, math.pi / 2, 0.64, 0.02, -0.1) == pytest.approx(
        (0.98, 1.64, math.pi / 2 - 0.1))


def test_track_point_round_trip() -> None:
    """Offsets measured from a known pose against a known tape give back the tape."""
    x, y, heading, ahead = 1.0, 2.0, 0.7, 0.64
    tape_at, tape_heading = np.array([1.9, 2.9]), 0.85
    along = np.array([math.cos(tape_heading), math.sin(tape_heading)])
    centre = np.array([x, y]) + ahead * np.array([math.cos(heading), math.sin(heading)])
    left = np.array([-math.sin(heading), math.cos(heading)])
    # The window's cross line meets the tape: centre + eps_d left = tape_at + t along.
    eps_d, _ = np.linalg.solve(np.column_stack([left, -along]), tape_at - centre)
    xp, yp, theta_p = track_point(x, y, heading, ahead, eps_d, tape_heading - heading)
    assert theta_p == pytest.approx(tape_heading)
    off = np.array([xp, yp]) - tape_at
    assert off[0] * along[1] - off[1] * along[0] == pytest.approx(0.0, abs=1e-12)  # on it
    assert np.array([xp, yp]) == pytest.approx(centre + eps_d * left, abs=1e-12)
