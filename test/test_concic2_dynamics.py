"""Dynamic CONCIC-II (Huang's model, App. G) with its LM628 loops (Rajagopalan 1991)."""

from __future__ import annotations

import math

import pytest

from agv_nodes.world.concic2_dynamics import (
    Concic2Dynamic,
    Concic2DynamicParams,
    motor_voltage_step,
)
from agv_nodes.world.lm628 import (
    LM628,
    SAMPLE_PERIOD,
    acceleration_code,
    counts_per_metre,
    velocity_code,
)
from agv_nodes.world.settings import Concic2Params

DT = 1.0 / 340.0 / 4.0  # the world's sub-step


def run(v: Concic2Dynamic, seconds: float, every: float = 0.0) -> list[tuple]:
    """Step for `seconds`; return (t, x, y, heading, v1, v2, theta1) every `every` s."""
    out = []
    n = int(round(seconds / DT))
    k_every = max(1, int(round(every / DT))) if every else n
    for k in range(1, n + 1):
        v.step(DT)
        if k % k_every == 0:
            s = v.state
            out.append((k * DT, s.x, s.y, s.heading, v.v1, v.v2, v.theta1))
    return out


def test_lm628_units() -> None:
    """The coded values of Eq. 6.5-6.9: 40,550 counts per wheel revolution, 15,104 per rpm."""
    cpm = counts_per_metre(0.075, 9.9)
    assert cpm * 2 * math.pi * 0.075 == pytest.approx(40550.4)
    rpm = 2 * math.pi * 0.075 / 60.0
    assert velocity_code(rpm, cpm) == pytest.approx(15104, rel=2e-3)  # thesis: dt = 341 us
    assert SAMPLE_PERIOD == pytest.approx(341.33e-6, rel=1e-4)
    chip = LM628(acceleration_code(0.3, cpm))
    chip.load_velocity(velocity_code(0.5, cpm))
    chip.start(0, 0.0)
    for _ in range(100):
        chip.sample(0)
    assert chip.profile == 100 * chip.acceleration  # the trapezoid's constant slope


def test_motor_alone_matches_datasheet() -> None:
    """Electrical 7.8 ms, mechanical 0.088 s (Eq. B.14-B.15), no-load 1700 rpm (Eq. B.11)."""
    p = Concic2DynamicParams()
    locked = motor_voltage_step(p, 24.0, 0.05, locked=True)
    i_final = 24.0 / p.armature_resistance
    t_e = next(t for t, i, _ in locked if i >= (1 - math.exp(-1)) * i_final)
    assert t_e == pytest.approx(0.0078, rel=0.1)
    free = motor_voltage_step(p, 24.0, 1.0)
    w_final = free[-1][2]
    assert w_final * 60 / (2 * math.pi) == pytest.approx(1700, rel=0.02)
    t_m = next(t for t, _, w in free if w >= (1 - math.exp(-1)) * w_final)
    assert t_m == pytest.approx(0.088, rel=0.1)


def wheel_speeds_from_position(log: list[tuple], n_r: float) -> list[tuple[float, float]]:
    """Left rim speed by encoder-angle difference over each logged interval, as the thesis did.

    The intervals are whole sub-steps (54 of them, 39.7 ms, for `every` = 0.04), so each is
    divided by the time that actually elapsed: dividing by a nominal 40 ms reads 0.74 % slow.
    """
    return [(b[0], (b[6] - a[6]) / n_r / (b[0] - a[0]))
            for a, b in zip(log, log[1:], strict=False)]


@pytest.mark.timeout(30)
def test_velocity_step_follows_trapezoid_and_settles() -> None:
    """0.63 m/s step: ramp at the programmed 0.3 m/s^2, overshoot, settle on the speed.

    The thesis saw 1 % overshoot (7.5.2.1, with its 0.024 m/s^2 ramp). This model gives 3.8 %
    here: the thesis gains close a position loop that only the back-EMF damps against the
    loaded wheel (about 0.1 of critical), and the lag built up on the ramp is released at its
    end; bound 5 %. The loop then rings down (period about 0.6 s) without a limit cycle: the
    DAC dithers between two adjacent codes.
    """
    v = Concic2Dynamic(Concic2DynamicParams())
    v.set_wheels(0.63, 0.63, True)
    log = run(v, 8.0, every=0.04)
    speeds = wheel_speeds_from_position(log, v.p.gear_ratio / v.p.wheel_radius)
    # After the first second (stiction delays the start, the position loop then catches up)
    # the wheel is on the profile a t within 0.03 m/s.
    assert all(abs(s - 0.3 * (t - 0.02)) < 0.03 for t, s in speeds if 1.2 <= t <= 2.0)
    peak = max(s for _, s in speeds)
    assert 0.63 * 1.02 < peak < 0.63 * 1.05
    # The LM628 closes a position loop, so the mean speed over a window is exact to within the
    # change of the count error over it (about 50 counts, 0.6 mm, from 6 s): 0.1 % over 2 s.
    a = next(r for r in log if r[0] >= 6.0)
    b = log[-1]
    mean = (b[6] - a[6]) / (v.p.gear_ratio / v.p.wheel_radius) / (b[0] - a[0])
    assert mean == pytest.approx(0.63, rel=0.001)
    # Settled, the 40 ms speed stays within the +-0.5 rpm the thesis read back (7.5.2.1).
    rpm = 2 * math.pi * v.p.wheel_radius / 60.0
    assert all(abs(s - 0.63) < 0.5 * rpm for t, s in speeds if t > 6.0)


@pytest.mark.timeout(60)
def test_startup_ramp_masks_differential() -> None:
    """Both wheels ramp together, so a turn command acts only once the ramp ends (7.3.2)."""
    v = Concic2Dynamic(Concic2DynamicParams())
    v.set_wheels(0.40, 0.50, True)  # a left turn from rest
    log = run(v, 2.5, every=0.02)
    ramp_end = 0.40 / 0.3
    during = [abs(r[5] - r[4]) for r in log if 0.2 < r[0] < ramp_end - 0.1]
    after = [r[5] - r[4] for r in log if r[0] > ramp_end + 0.5]
    assert max(during) < 0.01  # equal wheel speeds: no yaw while ramping
    assert sum(after) / len(after) == pytest.approx(0.10, abs=0.01)  # then the turn acts


def circle(v: Concic2Dynamic, speed: float, radius: float) -> None:
    """Command the wheel speeds of a left circle (Eq. 5.13-5.14)."""
    half = speed / radius * v.p.wheel_span / 2.0
    v.set_wheels(speed - half, speed + half, True)


@pytest.mark.timeout(30)
def test_steady_circle_and_caster_angle() -> None:
    """R 2.95 m at 0.63 m/s: yaw rate V/R, tan(theta_s) = psi_dot L_ae / V (Eq. 5.10-5.11)."""
    v = Concic2Dynamic(Concic2DynamicParams())
    circle(v, 0.63, 2.95)
    run(v, 6.0)
    h0 = v.state.heading
    angles = []
    window = 4.0  # s, exactly 5440 sub-steps
    for _ in range(int(round(window / DT))):
        v.step(DT)
        angles.append(v.caster_front)
    w = (v.state.heading - h0) / window
    assert v.state.speed == pytest.approx(0.63, rel=0.01)
    # Each wheel tracks its LM628 profile position, so the heading follows the profiles'
    # to within the difference of the two count errors, which wanders by about +-1 mrad once
    # the turn has settled: 0.3 % of the yaw over 4 s.
    assert w == pytest.approx(0.63 / 2.95, rel=0.005)
    p = v.p
    th = sum(angles) / len(angles)
    l_ae = p.caster_distance + p.caster_trail * (1 - math.cos(th))
    assert math.tan(th) == pytest.approx(w * l_ae / 0.63, rel=0.02)
    assert v.caster_rear == pytest.approx(-th, rel=0.05)  # the rear caster swings outwards


@pytest.mark.timeout(60)
def test_smooth_stop_on_curve_drifts_inside() -> None:
    """Equal deceleration: the faster outer wheel stops last, the truck turns in (6.3.2)."""
    v = Concic2Dynamic(Concic2DynamicParams())
    radius = 2.95
    circle(v, 0.63, radius)
    run(v, 5.0)
    s = v.state
    cx, cy = s.x - radius * math.sin(s.heading), s.y + radius * math.cos(s.heading)
    h0 = s.heading
    v.set_wheels(0.0, 0.0, True)
    run(v, 3.0)
    turned = v.state.heading - h0
    travelled = math.hypot(v.state.x - cx, v.state.y - cy)
    assert v.state.speed == pytest.approx(0.0, abs=1e-3)
    assert travelled < radius - 0.003  # inside the circle it was on
    arc = 0.63 ** 2 / (2 * 0.3)  # the stopping distance of the centre
    assert turned > 1.2 * arc / radius  # more yaw than a proportional stop would give


def coast_distance(v: Concic2Dynamic, speed: float, radio: bool) -> tuple[float, float]:
    """Cruise at `speed`, cut the drive; return the distance to rest and the speed at the cut."""
    v.set_wheels(speed, speed, True)
    run(v, speed / 0.3 + 2.0)
    x0, v0 = v.state.distance, v.state.speed
    if radio:
        v.radio_stop = True
    else:
        v.set_wheels(0.0, 0.0, False)
    run(v, 1.0)
    assert v.state.speed == 0.0
    return v.state.distance - x0, v0


@pytest.mark.timeout(30)
def test_motor_off_coast() -> None:
    """Motor off from 0.16 m/s: zero terminal voltage, so back-EMF braking plus friction.

    The thesis measured 5 mm (7.3.4); no consistent reading of the drive gives that (see the
    concic2_dynamics docstring). The model is held to its own physics: linear braking c plus
    Coulomb force F stop a mass m from v0 in d = (m/c)(v0 - (F/c) ln(1 + c v0 / F)), and the
    braking starts only after the amplifier (1 ms) and armature (L/R 7.8 ms) lags, which add
    about v0 times their sum. The speed at the cut is the loop's, which ripples a few % at
    0.16 m/s. An E-stop (relays open) has no electrical braking and goes further.
    """
    v = Concic2Dynamic(Concic2DynamicParams())
    d, v0 = coast_distance(v, 0.157, radio=False)
    p = v.p
    n_r = v._n_r
    c = 2 * n_r ** 2 * (p.torque_constant * p.back_emf_constant / p.armature_resistance
                        + p.viscous_friction)
    f = 2 * p.coulomb_friction * n_r + 4 * p.rolling_k1 * v._normal
    m = v.m_v
    lags = p.amplifier_time_constant + p.armature_inductance / p.armature_resistance
    expected = m / c * (v0 - f / c * math.log(1 + c * v0 / f)) + v0 * lags
    assert d == pytest.approx(expected, rel=0.05)
    assert 0.015 < d < 0.025  # four times the thesis's 5 mm, for the reasons documented
    e_stop, _ = coast_distance(Concic2Dynamic(Concic2DynamicParams()), 0.157, radio=True)
    assert e_stop > 1.3 * d


@pytest.mark.timeout(30)
def test_no_motion_without_current() -> None:
    """Nothing moves with zero demand, nor with a demand while the radio stop holds."""
    v = Concic2Dynamic(Concic2DynamicParams())
    v.set_wheels(0.0, 0.0, True)
    run(v, 1.0)
    assert v.state.distance == 0.0 and v.v1 == 0.0 and v.v2 == 0.0
    v.radio_stop = True
    v.set_wheels(0.5, 0.5, True)
    run(v, 1.0)
    assert v.state.distance == 0.0 and v.i1 == 0.0 and v.i2 == 0.0


@pytest.mark.timeout(60)
def test_deterministic_and_from_params() -> None:
    """Same inputs, same trajectory; geometry comes from Concic2Params."""
    logs = []
    for _ in range(2):
        v = Concic2Dynamic(Concic2Params())
        circle(v, 0.47, 2.0)
        logs.append(run(v, 2.0, every=0.1))
    assert logs[0] == logs[1]
    assert v.p.wheel_span == Concic2Params().wheel_span
    assert v.kind == 'concic2'
