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
from agv_nodes.world.vehicles import Concic2

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


def servo_lag(p: Concic2DynamicParams) -> float:
    """Return how far (s) a wheel trails its LM628 profile on a ramp, from the parameters.

    The LM628's P term on the position error sets the speed loop's input; the amplifier's
    speed loop holds the speed that input asks for (max_wheel_speed per full_speed_input
    volts). So the position loop's crossover is the speed per count of error times the counts
    per metre, and a ramp is followed 1 / crossover plus the speed loop's own time constant
    behind: the truck's mass (and the rotors') over the speed loop's damping at both wheels.
    """
    n_r = p.gear_ratio / p.wheel_radius
    per_code = p.dac_volts_per_code * p.max_wheel_speed / p.full_speed_input  # m/s
    crossover = per_code * p.kp / 2 ** p.output_shift * counts_per_metre(p.wheel_radius,
                                                                          p.gear_ratio)
    m_v = p.mass + p.payload + 2 * n_r ** 2 * p.rotor_inertia
    tau = m_v / (2 * n_r ** 2 * (p.torque_constant * p.velocity_gain + p.viscous_friction))
    return 1.0 / crossover + tau


@pytest.mark.timeout(30)
def test_velocity_step_follows_trapezoid_and_settles() -> None:
    """0.63 m/s step: ramp at the programmed 0.3 m/s^2 a servo lag behind, settle on the speed.

    The wheel trails the profile by the lag servo_lag derives (about 0.18 s; 6.3.8 puts the
    servo loop's time constant at four vision cycles, 0.18 s), overshoots by under 2 % (the
    thesis saw 1 %, 7.5.2.1) and then holds the speed within the +-0.5 rpm the thesis read back.
    """
    v = Concic2Dynamic(Concic2DynamicParams())
    v.set_wheels(0.63, 0.63, True)
    log = run(v, 8.0, every=0.04)
    speeds = wheel_speeds_from_position(log, v.p.gear_ratio / v.p.wheel_radius)
    lag = servo_lag(v.p)
    on_ramp = [t - s / 0.3 for t, s in speeds if 0.5 <= t <= 2.0]
    assert sum(on_ramp) / len(on_ramp) == pytest.approx(lag, rel=0.15)
    assert all(abs(x - lag) < 0.04 for x in on_ramp)  # a steady ramp, not a ringing one
    peak = max(s for _, s in speeds)
    assert 0.63 < peak < 0.63 * 1.02
    # The LM628 closes a position loop, so the mean speed over a window is exact to within the
    # change of the count error over it: 0.1 % over 2 s.
    a = next(r for r in log if r[0] >= 6.0)
    b = log[-1]
    mean = (b[6] - a[6]) / (v.p.gear_ratio / v.p.wheel_radius) / (b[0] - a[0])
    assert mean == pytest.approx(0.63, rel=0.001)
    rpm = 2 * math.pi * v.p.wheel_radius / 60.0
    assert all(abs(s - 0.63) < 0.5 * rpm for t, s in speeds if t > 4.0)


def differential_step(v: Concic2 | Concic2Dynamic, speed: float, half: float,
                      seconds: float) -> tuple[list[tuple[float, float]], float]:
    """Cruise, then step the wheels to speed -+ half; return (t, yaw rate) and the heading turned.

    Yaw rate from the wheel speeds every sub-step; t from the step.
    """
    v.set_wheels(speed, speed, True)
    for _ in range(int(round(4.0 / DT))):
        v.step(DT)
    h0 = v.state.heading
    v.set_wheels(speed - half, speed + half, True)
    out = []
    for k in range(1, int(round(seconds / DT)) + 1):
        v.step(DT)
        left, right = v.wheel_speeds()
        out.append((k * DT, (right - left) / v.p.wheel_span))
    return out, v.state.heading - h0


@pytest.mark.timeout(30)
def test_differential_step_damped_like_the_kinematic_truck() -> None:
    """A 0.06 m/s differential step at 0.47 m/s: the yaw rate the kinematic model gives.

    The steady yaw rate is (v2 - v1) / L within 0.2 % (the wheels' speed ratio is held), and
    the heading turned over 3 s within 5 % of the kinematic Concic2's. The response is near
    critically damped, as the thesis tuned the drive (C.2.3.5: 5 % overshoot): under 10 %
    overshoot (a voltage-source amplifier gave 79 %, and rang at 1.2 Hz); 63 % within the
    trapezoid's 0.1 s plus the servo lag.
    """
    dyn, turned = differential_step(Concic2Dynamic(Concic2DynamicParams()), 0.47, 0.03, 3.0)
    kin, turned_kin = differential_step(Concic2(Concic2Params()), 0.47, 0.03, 3.0)
    target = 0.06 / 0.52
    late = [w for t, w in dyn if t > 2.0]
    assert sum(late) / len(late) == pytest.approx(target, rel=0.002)
    assert kin[-1][1] == pytest.approx(target, rel=1e-6)
    assert turned == pytest.approx(turned_kin, rel=0.05)
    assert max(w for _, w in dyn) < 1.10 * target
    t63 = next(t for t, w in dyn if w >= 0.632 * target)
    assert t63 < 0.1 + servo_lag(Concic2DynamicParams())


@pytest.mark.timeout(30)
def test_servo_loop_time_constant_within_the_thesis_bound() -> None:
    """The servo loop alone (the trapezoid a step): 63 % of a yaw-rate step in 0.16-0.24 s.

    6.3.8: "the cycle time is one quarter of the time constant of the servo loop"; the cycle is
    40-60 ms (6.3.10: 16-25 frames a second; 7.5.1.6: "varies from 40 ms to 60 ms").
    """
    p = Concic2DynamicParams(acceleration=30.0)
    dyn, _turned = differential_step(Concic2Dynamic(p), 0.47, 0.03, 1.0)
    target = 0.06 / p.wheel_span
    t63 = next(t for t, w in dyn if w >= 0.632 * target)
    assert 4 * 0.040 <= t63 <= 4 * 0.060


@pytest.mark.timeout(30)
def test_no_yaw_on_a_straight_command() -> None:
    """Equal wheel commands at cruise: no steady yaw (no caster side force or friction bias)."""
    v = Concic2Dynamic(Concic2DynamicParams())
    v.set_wheels(0.79, 0.79, True)
    run(v, 4.0)
    h0, y0 = v.state.heading, v.state.y
    run(v, 6.0)
    assert abs(v.state.heading - h0) < 1e-3  # rad over 4.7 m
    assert abs(v.state.y - y0) < 2e-3


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
def test_motor_off_stops_in_5_mm() -> None:
    """Motor off from 0.16 m/s: zero input, the amplifier's speed loop brakes: about 5 mm.

    The thesis measured 5 mm (7.3.4, Fig. 7.9). The speed loop brakes linearly, c = 2 (n/r)^2
    (K_t G_v + b), with Coulomb friction F besides, which stops a mass m from v0 in
    d = (m/c)(v0 - (F/c) ln(1 + c v0 / F)); the 36 A limit, reached in the first few ms, and the
    current's lag lengthen it a little: within 20 %. An E-stop (relays open) has no braking
    current and coasts on friction alone, several times further.
    """
    v = Concic2Dynamic(Concic2DynamicParams())
    d, v0 = coast_distance(v, 0.157, radio=False)
    p = v.p
    n_r = v._n_r
    c = 2 * n_r ** 2 * (p.torque_constant * p.velocity_gain + p.viscous_friction)
    f = 2 * p.coulomb_friction * n_r + 4 * p.rolling_k1 * v._normal
    expected = v.m_v / c * (v0 - f / c * math.log(1 + c * v0 / f))
    assert d == pytest.approx(expected, rel=0.2)
    assert 0.004 < d < 0.0065
    e_stop, _ = coast_distance(Concic2Dynamic(Concic2DynamicParams()), 0.157, radio=True)
    assert e_stop > 3.0 * d


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
