"""Rajagopalan 1991, Chapter 9's extensions (system 15): each law against its equation, by hand.

The expected values are the thesis's equations (9.5-9.10, 9.15-9.16, the concavity test of 9.5)
evaluated by hand in each test, or the geometry of a straight tape drawn in the test, never the
code's own formula. The lock-step tests take the runs of bench/chapter9_bench.py (world
ground truth, seeded): an option off leaves the camera law bit-identical to the defaults, and
the inflexion option on does no worse on the S-bend than the defaults, within the defaults'
seed-to-seed spread measured there (bench/results/chapter9_bench.md).
"""

from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path
import sys

import pytest

from agv_nodes.route_following.camera_guidance import (
    CameraSteering,
    Measurement,
    Validity,
    WindowPredictor,
)
from agv_nodes.route_following.camera_law import CameraLaw
from agv_nodes.route_following.chapter9 import (
    InflexionDetector,
    InflexionPredictor,
    SpeedScaledSteering,
    concavity,
    reference_offset,
    reference_offset_thesis,
    speed_law_increments,
    steering_law,
)
from agv_nodes.route_following.dual_camera import DualCameraGuidance, Offsets
from agv_nodes.route_following.settings import Chapter9Params, RouteParams, SteeringParams
from agv_nodes.world.concic2_dynamics import Concic2Dynamic, Concic2DynamicParams
from agv_nodes.world.lm628 import LM628
from agv_nodes.world.wheel_loops import WheelLoops, cartesian_error, cross_coupled_error

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bench'))
import chapter9_bench as bench  # noqa: E402


@pytest.mark.timeout(10)
def test_speed_law_wheel_increments_by_hand() -> None:
    """Eq. 9.5-9.9 with V 0.5 m/s, eps_thetad 0.3, eps_thetaa 0.1, G1 2.5, G2 0.2.

    1 / sin 0.3 = 3.383863, 1 / cos 0.1 = 1.005021: the brace is 2.378842. (L_a - s) / s - G2
    = (0.31 - 0.05) / 0.05 - 0.2 = 5.0. Eq. 9.7: d_omega_1 - d_omega_2 = 0.52 x 0.5 x 2.5 x
    2.378842 / (0.075 x 5.0) = 4.123327 rad/s; Eq. 9.8 with L1 = L2 splits it evenly.
    """
    d1, d2 = speed_law_increments(0.5, 0.3, 0.1, 2.5, 0.2, 0.26, 0.26, 0.075, 0.31, 0.05)
    assert d1 == pytest.approx(2.061663, abs=1e-6)
    assert d2 == pytest.approx(-2.061663, abs=1e-6)
    # L1 0.2, L2 0.3 (Eq. 9.9-9.10): G1 L2 V {..} / (r [..]) = 2.5 x 0.3 x 0.5 x 2.378842 /
    # 0.375 = 2.378842 and -2.5 x 0.2 x 0.5 x 2.378842 / 0.375 = -1.585895.
    d1, d2 = speed_law_increments(0.5, 0.3, 0.1, 2.5, 0.2, 0.2, 0.3, 0.075, 0.31, 0.05)
    assert (d1, d2) == pytest.approx((2.378842, -1.585895), abs=1e-6)
    assert 0.2 * d1 + 0.3 * d2 == pytest.approx(0.0, abs=1e-12)  # Eq. 9.8: speed kept
    with pytest.raises(ValueError, match='1 / sin'):
        speed_law_increments(0.5, 0.0, 0.1, 2.5, 0.2, 0.26, 0.26, 0.075, 0.31, 0.05)


@pytest.mark.timeout(10)
def test_reference_point_as_printed_by_hand() -> None:
    """Eq. 9.15 and 9.16 with L1 0.4, L2 0.88 (L1 / (L1 + L2) = 0.3125).

    Same signs 0.02, 0.06: (0.08 x 0.3125 + min(0.02, 0.06)) x +1 = 0.045. Opposite, 0.02 and
    -0.06: 0.04 x 0.3125 x +1 - (-0.06) = 0.0725.
    """
    assert reference_offset_thesis(0.02, 0.06, 0.4, 0.88) == pytest.approx(0.045, abs=1e-12)
    assert reference_offset_thesis(0.02, -0.06, 0.4, 0.88) == pytest.approx(0.0725, abs=1e-12)
    assert reference_offset_thesis(-0.02, -0.06, 0.4, 0.88) == pytest.approx(-0.045, abs=1e-12)


@pytest.mark.timeout(10)
@pytest.mark.parametrize('a,b', [(0.03, 0.05), (-0.02, 0.1), (0.01, -0.2)])
def test_reference_point_on_a_drawn_tape(a: float, b: float) -> None:
    """A straight tape y = a + b x in the body frame; the windows at +-0.64 m, c at +0.24 m.

    The perpendiculars across the axis meet it at a + 0.64 b, a - 0.64 b and a + 0.24 b.
    """
    front, rear, c = a + 0.64 * b, a - 0.64 * b, a + 0.24 * b
    assert reference_offset(front, rear, 0.4, 0.88) == pytest.approx(c, abs=1e-12)


@pytest.mark.timeout(10)
def test_concavity_and_inflexion_by_hand() -> None:
    """Concave up for f'' > 0, down for < 0 (Sec. 9.5); a change holds over `frames` readings."""
    assert (concavity(0.4), concavity(-0.4), concavity(0.1, 0.2)) == (1, -1, 0)
    detector = InflexionDetector(dead=0.2, frames=3)
    got = [detector.update(f) for f in (0.5, 0.5, -0.5, -0.5, 0.1, 0.5, -0.5, -0.5, -0.1,
                                        -0.5, -0.5)]
    # 0.5 holds up; two downs broken by an up; then three downs in a row (0.1 / -0.1 within
    # the dead band neither count nor break the run): the change at the 10th reading.
    assert got == [False] * 9 + [True, False]
    assert detector.sign == -1
    assert detector.mean == pytest.approx(-0.5, abs=1e-12)


@pytest.mark.timeout(10)
def test_wheel_loops_by_hand() -> None:
    """9.2.1: e1 - e2 for equal shares; 9.2.2: the reference 0.1 m ahead, 0.02 m left."""
    assert cross_coupled_error(0.004, 0.001) == pytest.approx(0.003, abs=1e-15)
    # Shares 0.25 / 0.75: 2 (0.75 x 0.004 - 0.25 x 0.001) = 0.0055.
    assert cross_coupled_error(0.004, 0.001, 0.25) == pytest.approx(0.0055, abs=1e-15)
    # Truck at (1, 2) heading 90 deg; the reference at (0.98, 2.1) heading 100 deg.
    along, across, turn = cartesian_error((1.0, 2.0, math.pi / 2), (0.98, 2.1, math.radians(100)))
    assert (along, across, turn) == pytest.approx((0.1, 0.02, math.radians(10)), abs=1e-12)


def _frames() -> list[Measurement]:
    """Return a fixed run of readings across an S: left-turning tape, then right (rad, m)."""
    out = []
    for k in range(80):
        theta = 0.1 * math.sin(k / 8.0) + 0.003 * ((k * 37) % 7 - 3)
        out.append(Measurement(0.01 * math.cos(k / 5.0), theta, Validity.NORMAL, 6.0, 64,
                               False, False))
    return out


def _angles(law: CameraSteering, speed: float) -> list[float | None]:
    return [law.update(m, 0.05, speed) for m in _frames()]


@pytest.mark.timeout(10)
def test_options_off_are_the_plain_law() -> None:
    """With chapter9 off the camera law is the plain CameraSteering and WindowPredictor."""
    law = CameraLaw(replace(RouteParams(), vehicle='concic2')).single
    assert type(law) is CameraSteering and type(law.predictor) is WindowPredictor
    steering = SteeringParams()
    off = steering_law(steering, 0.64, Chapter9Params(inflexion_frames=7))
    assert _angles(off, 0.63) == _angles(CameraSteering(steering, 0.64), 0.63)


@pytest.mark.timeout(10)
def test_speed_law_at_its_reference_speed_is_the_plain_law() -> None:
    """V / V_ref = 1 scales nothing; at 2 V_ref the P gains double (9.3)."""
    steering = SteeringParams(predict=0.0, law='p', gain_theta=0.484375)
    scaled = SpeedScaledSteering(steering, 0.64, 0.47)
    assert _angles(scaled, 0.47) == _angles(CameraSteering(steering, 0.64), 0.47)
    m = Measurement(0.01, 0.02, Validity.NORMAL, 6.0, 64, False, False)
    # Eq. 5.4 with 2 x 2.5 and 2 x 0.484375: 5.0 x 0.01 + 0.96875 x 0.02 = 0.069375 rad.
    theta = SpeedScaledSteering(steering, 0.64, 0.47).update(m, 0.05, 0.94)
    assert theta == pytest.approx(0.069375, abs=1e-12)
    # per_time at 2 V_ref halves them: 1.25 x 0.01 + 0.2421875 x 0.02 = 0.01734375 rad.
    theta = SpeedScaledSteering(steering, 0.64, 0.47, 'per_time').update(m, 0.05, 0.94)
    assert theta == pytest.approx(0.01734375, abs=1e-12)


@pytest.mark.timeout(10)
def test_speed_law_as_derived_is_the_plain_law() -> None:
    """speed_form once: Eq. 9.9-9.10's V is Eq. 5.15-5.16's, so the gains stay as they are."""
    steering = SteeringParams()
    once = steering_law(steering, 0.64, Chapter9Params(speed_reference=0.47))
    assert type(once) is CameraSteering
    assert _angles(once, 0.79) == _angles(CameraSteering(steering, 0.64), 0.79)
    with pytest.raises(ValueError, match='speed_form'):
        SpeedScaledSteering(steering, 0.64, 0.47, 'once')


@pytest.mark.timeout(10)
def test_cross_coupled_correction_by_hand() -> None:
    """Errors 10 and 4 counts, equal speeds, coupling 0.5: 0.5 x (10 - 4) = 3 on, 3 off."""
    left, right = LM628(1), LM628(1)
    left.desired = right.desired = 100 << 16
    assert WheelLoops(0.5, 0.0, 0.52, 1000.0).corrections(left, right, 90, 96) == (3, -3)
    assert WheelLoops(0.0, 0.0, 0.52, 1000.0).corrections(left, right, 90, 96) == (0, 0)
    # In a turn, the left profile twice the right's: shares 2/3, 1/3 (Borenstein and Koren),
    # 2 (1/3 x 10 - 2/3 x 4) = 1.333 counts, coupling 3: 4.
    left.profile, right.profile = 2 << 16, 1 << 16
    assert WheelLoops(3.0, 0.0, 0.52, 1000.0).corrections(left, right, 90, 96) == (4, -4)


@pytest.mark.timeout(10)
def test_cartesian_correction_by_hand() -> None:
    """1000 counts a metre, span 0.5 m: both chips' desired 1 m on, the left wheel 0.99 m.

    Reference: (1, 0, 0). Actual, midpoint rule: turn 0.01 / 0.5 = 0.02 rad, at 0.01 rad for
    0.995 m: (0.99495025, 0.00994983, 0.02). In the truck's frame: along 0.00484976, across
    -0.01004883, heading -0.02; turn -0.02 - 0.01004883 / 0.5 = -0.04009766. Gain 1: left
    1000 (0.00484976 + 0.25 x 0.04009766) = 14.87 -> 15; right 1000 (0.00484976 - 0.01002442)
    = -5.17 -> -5: the lagging left wheel pushes, and the truck turns back right.
    """
    left, right = LM628(1), LM628(1)
    loops = WheelLoops(0.0, 1.0, 0.5, 1000.0)
    assert loops.corrections(left, right, 0, 0) == (0, 0)
    left.desired = right.desired = 1000 << 16
    assert loops.corrections(left, right, 990, 1000) == (15, -5)
    assert loops.actual == pytest.approx([0.99495025, 0.00994983, 0.02], abs=1e-8)


def _knock(cross_coupling: float, cartesian_gain: float) -> tuple[float, float]:
    """Return (largest |heading| mrad, final lateral offset mm) after a knock on the left wheel.

    The dynamic CONCIC-II at 0.5 m/s straight on; at 3 s the left rim loses 0.2 m/s (a bump,
    9.2's environmental errors); 3 s later the run ends.
    """
    truck = Concic2Dynamic(Concic2DynamicParams(cross_coupling=cross_coupling,
                                                cartesian_gain=cartesian_gain))
    truck.set_wheels(0.5, 0.5, True)
    worst = 0.0
    for k in range(6000):
        if k == 3000:
            truck.v1 -= 0.2
        truck.step(0.001)
        worst = max(worst, abs(truck.state.heading))
    return 1000.0 * worst, 1000.0 * abs(truck.state.y)


@pytest.mark.timeout(60)
def test_wheel_loops_after_a_knock() -> None:
    """9.2: the cross-coupled loop turns the truck less; the Cartesian one leaves less offset.

    Independent loops bring each wheel back to its own desired position, so the heading comes
    back but the sideways step taken meanwhile stays (9.2.2's lag in Cartesian terms). The
    cross-coupled loop holds the other wheel back while one lags (9.2.1): less turn, less
    step. The Cartesian loop steers the truck back onto the line its chips meant (9.2.2).
    """
    alone = _knock(0.0, 0.0)
    coupled = _knock(1.0, 0.0)
    cartesian = _knock(1.0, 1.0)
    assert coupled[0] < alone[0] and coupled[1] < alone[1], (coupled, alone)
    assert cartesian[1] < coupled[1], (cartesian, coupled)


@pytest.mark.timeout(10)
def test_reference_point_switches_the_gains_at_c() -> None:
    """9.6: the high gains end where the tape crosses c, here the axle centre, not the lead.

    Started with both windows left of the tape; then the lead 0.01 m right, the trail 0.05 m
    left: the front end has crossed, c (halfway) has not: -0.01 + 0.06 / 2 = +0.02 m, still
    left. Then the trail at 0.005 m: c at -0.0025 m has crossed.
    """
    start, lead, trail = Offsets(0.05, 0.0), Offsets(-0.01, 0.0), Offsets(0.05, 0.0)
    front_end, at_c = DualCameraGuidance(), DualCameraGuidance()
    at_c.reference_point = 0.64
    for law in (front_end, at_c):
        law.steer(start, start, 0.05)
        law.steer(lead, trail, 0.05)
    assert front_end.decision.crossed and not at_c.decision.crossed
    at_c.steer(lead, Offsets(0.005, 0.0), 0.05)
    assert at_c.decision.crossed


@pytest.mark.timeout(10)
def test_inflexion_restarts_the_curvature() -> None:
    """The tape's curvature flips from +0.4 to -0.4 /m under a truck driving straight.

    The plain predictor's filter (a share 0.3 a frame) is two frames after the flip at
    0.4 x 0.7^2 - 0.4 x (1 - 0.7^2) = -0.008 /m; with the inflexion found (dead 0.2, 2 frames)
    the estimate is the new -0.4 then.
    """
    steering, v, dt = SteeringParams(predict=0.15, curvature_filter=0.3), 0.5, 0.05
    plain = WindowPredictor(steering, 0.64)
    found = InflexionPredictor(steering, 0.64, Chapter9Params(inflexion_curvature=0.2,
                                                              inflexion_frames=2))
    alpha = 0.0
    for k in range(42):
        alpha += (0.4 if k < 40 else -0.4) * v * dt
        plain.predict(0.0, alpha, dt, v)
        found.predict(0.0, alpha, dt, v)
    # 1e-6: what is left of the filter's start at 0 after 40 frames, 0.4 x 0.7^40 = 2.5e-7.
    assert plain.kappa == pytest.approx(-0.008, abs=1e-6)
    assert found.kappa == pytest.approx(-0.4, abs=1e-9)


@pytest.mark.timeout(240)
def test_inflexion_off_is_bit_identical_in_lock_step() -> None:
    """S-bend at 0.79 m/s, kinematic: chapter9 off with a non-default frames count = defaults."""
    a = bench.run('sbend', 'kinematic', 0.79, Chapter9Params(), 2)
    b = bench.run('sbend', 'kinematic', 0.79, Chapter9Params(inflexion_frames=9), 2)
    assert a == b


@pytest.mark.timeout(240)
def test_speed_law_as_derived_is_bit_identical_in_lock_step() -> None:
    """speed_form once (the default form) with speed_reference on: the defaults, bit for bit."""
    on = Chapter9Params(speed_reference=0.47)
    assert bench.run('step', 'kinematic', 0.79, on, 2) == \
        bench.run('step', 'kinematic', 0.79, Chapter9Params(), 2)


def _judged(config: str, kind: str, model: str, speed: float) -> tuple[str, list, list]:
    """Run a bench configuration and the row it is judged against, seeds 2-4, in lock step.

    Return the bench's verdict (its rule: the option's seeds' mean within the baseline's mean
    plus the baseline's own seed spread) and both rows' results.
    """
    c = bench.CONFIGS[config]
    base = bench.CONFIGS[c.against]
    rows = [[bench.run(kind, model, speed, x.options, seed, x.wheels, x.steering)
             for seed in (2, 3, 4)] for x in (c, base)]
    option, baseline = ({q: [r[q] for r in runs] for q in bench.QUANTITIES} for runs in rows)
    return bench.verdict(option, baseline), rows[0], rows[1]


# (configuration, experiment, model, speed): the rows of bench/results/chapter9_bench.md where
# each option does no worse than what it is judged against; the rows where it is worse are
# named in each test's docstring (and marked in the bench's table).
NO_WORSE = [
    ('speed law (9.3), per_time', 'circle', 'dynamic', 0.63),
    ('speed law (9.3), gains', 'sbend', 'dynamic', 0.79),
    ('inflexion (9.5) on the predictor', 'step', 'kinematic', 0.31),
    ('Cartesian (9.2.2)', 'circle', 'dynamic', 0.63),
]


@pytest.mark.timeout(600)
@pytest.mark.parametrize('config,kind,model,speed', NO_WORSE)
def test_option_no_worse_where_the_bench_finds_it(config: str, kind: str, model: str,
                                                  speed: float) -> None:
    """Each Chapter 9 option, lock step, seeds 2-4, no worse on a representative row.

    Judged against the defaults of the code run (the thesis's law at commit 97935b2). Worse
    rows, not asserted (docs/chapter9.md): at the thesis's law, gains on the steps and the
    circle, per_time on the S-bends, and the cross-coupled loop alone on every row tried (on
    the 0.79 m/s step, dynamic model, it loses the tape; its test is the knock above). At the
    curve settings of commit d573354 (the bench table of commit 518f848): gains on every row,
    per_time on all but the dynamic model's steps, the inflexion on the kinematic S-bend at
    0.63 m/s, the cross-coupled loop on all but the 0.31 m/s step, the Cartesian loop on all
    but the S-bend at 0.79 m/s. The option must also hold the tape on every seed.
    """
    mark, option, baseline = _judged(config, kind, model, speed)
    assert mark == 'no worse', (mark, option, baseline)
    assert all(math.isfinite(r['peak']) for r in option), option


# (start, model): the dual-camera rows where the gains switched at c (the axle centre) do no
# worse than at the front end (bench/results/chapter9_bench.md, the reference point's table).
DUAL_NO_WORSE = [('straight, opposite sides', 'kinematic'),
                 ('straight, opposite sides', 'dynamic'),
                 ('circle R = 3.0 m, opposite sides', 'dynamic')]


@pytest.mark.timeout(600)
@pytest.mark.parametrize('start,model', DUAL_NO_WORSE)
def test_reference_point_no_worse_where_the_bench_finds_it(start: str, model: str) -> None:
    """9.6 at c = 0.64 m (the axle centre) against the front end, lock step, seeds 2-4.

    Worse, by the bench (docs/chapter9.md): both same-side starts (the rear window takes
    longer: the high start gain ends only once the middle of the truck has crossed) and the
    opposite-sides start on the circle on the kinematic model.
    """
    name, radius, front, rear, _thesis = next(s for s in bench.dual_bench.SCENARIOS
                                              if s[0] == start)
    rows = [[bench.dual_run(radius, front, rear, model, reference, seed) for seed in (2, 3, 4)]
            for reference in (bench.REFERENCE, 0.0)]
    at_c, front_end = ({q: [r[q] for r in runs] for q in bench.DUAL_QUANTITIES}
                       for runs in rows)
    mark = bench.verdict(at_c, front_end, bench.DUAL_QUANTITIES)
    assert mark == 'no worse', (name, mark, rows)
