"""Road signs read with the window skewed to the truck, as our curve settings hold it.

Our curve settings (bench/concic2_curvature_bench.py OURS; not the defaults, docs/camera_truck.md).
With the tape's orientation fed back (steering.gain_theta) the window stays on the tape of a
circle of radius R with the truck turned asin(L_c / R) from the tape under it: every sign on a
circle is crossed skewed. Over a sign its patch and branches turn the fitted line by tens of
degrees (a branch); fed back, that turned the truck onto the branch, which then read as a
straight on (P11 as P21) or left the circle's signs misread (Rajagopalan 1991, 4.3: 100 % of
the signs decoded). The expected signs are the layout files', the skew the circle's geometry.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from agv_nodes.harness import Harness
from agv_nodes.route_following.camera_guidance import (
    CameraSteering,
    Measurement,
    Validity,
    sign_name,
)
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams, SteeringParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import WorldParams

LC = WorldParams().concic2.camera_distance  # m, L_c of the world's CONCIC-II
OURS = SteeringParams(gain_theta=0.484375, integral_band=0.01, predict=0.15)


class SignReader:
    """A stand-in executive: camera mode straight on; each sign's name once it is behind."""

    node, period = 'executive', 0.05

    def __init__(self) -> None:
        self.signs: list[str | None] = []
        self.state = ''

    def on_record(self, record, fields, now):
        if record == 'route_status':
            if self.state == 'sign' and fields['state'] != 'sign':
                self.signs.append(sign_name(fields['sign_left'], fields['sign_right'],
                                            fields['sign_straight']))
            self.state = fields['state']
        return None

    def tick(self, now):
        return {'route_command': dict(mode='camera', srm_angle=0, manoeuvre=0, leg=1,
                                      junction='straight', junction_number=0)}


def _circle(tmp_path: Path, radius: float) -> Path:
    """tape_1991's floor and signs with the circle's radius `radius` (signs a third apart)."""
    third = 2.0 * math.pi * radius / 3.0
    text = f"""layout: skew
vehicle: concic2
kind: tape
tapes:
  - {{id: circle, start: [0.0, {-radius}, 0.0], width: 0.058,
      segments: [{{arc: {radius}, angle: 360}}]}}
signs:
  - {{type: R2, path: circle, at: {third:.3f}}}
  - {{type: P22, path: circle, at: {1.6 * third:.3f}}}
  - {{type: P21, path: circle, at: {2.4 * third:.3f}}}
start: {{path: circle, at: 0.3}}
"""
    path = tmp_path / 'skew.yaml'
    path.write_text(text)
    return path


@pytest.mark.timeout(240)
@pytest.mark.parametrize('radius, speed', [(2.0, 0.16), (2.0, 0.79), (3.0, 0.16), (3.0, 0.79)])
def test_signs_on_a_circle_read_with_the_window_skewed(tmp_path, radius, speed):
    """Each sign of the circle read as the layout names it, crossed at asin(L_c / R) skew."""
    lay = load_layout(_circle(tmp_path, radius))
    world = WorldCore(lay, WorldParams(seed=11))  # the dynamic model, the world's default
    reader = SignReader()
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed, steering=OURS))
    h = Harness(world, [reader, route])
    circle = lay.paths['circle']
    skews: list[float] = []

    def at_sign() -> bool:
        if reader.state == 'sign' and len(skews) == len(reader.signs):
            _s, _off, tape = circle.project(*world.vehicle.sensor_point)
            skews.append((tape - world.vehicle.state.heading + math.pi) % (2 * math.pi)
                         - math.pi)
        return len(reader.signs) == len(lay.signs)

    h.run(circle.length / speed + 5.0, until=at_sign)
    assert reader.signs == [s['type'] for s in lay.signs]
    assert route.state == 'following' and world.vehicle.state.speed > 0.9 * speed
    # The skew is the circle's, not a law's: the tape turned left of the truck by asin(L_c / R)
    # where the window meets each sign (within a degree: the window's own offset, mm, turns it
    # by well under that).
    want = math.asin(LC / radius)
    assert skews and all(abs(s - want) < math.radians(1.0) for s in skews), (
        [round(math.degrees(s), 2) for s in skews], round(math.degrees(want), 2))


def _frame(eps_d: float, eps_theta: float, validity: Validity) -> Measurement:
    return Measurement(eps_d, eps_theta, validity, 30.0 if validity is Validity.NORMAL
                       else 48.0, 64, False, False)


@pytest.mark.timeout(10)
@pytest.mark.parametrize('branch', [math.radians(45.0), math.radians(-78.0)])
def test_a_sign_frame_steers_by_the_last_plain_orientation(branch):
    """A wide frame's fitted angle (a branch) steers as the last plain frame's angle would."""
    p = OURS
    plain = math.asin(LC / 2.0)  # the window on a circle of R 2.0 m
    got, same = CameraSteering(p, LC), CameraSteering(p, LC)
    for steering in (got, same):
        for _ in range(20):
            steering.update(_frame(0.002, plain, Validity.NORMAL), 0.05, 0.47)
    for _ in range(5):  # over the sign: its branch turns the fit, the offset as measured
        theta = got.update(_frame(0.004, branch, Validity.WIDE), 0.05, 0.47)
        want = same.update(_frame(0.004, plain, Validity.WIDE), 0.05, 0.47)
        assert theta == pytest.approx(want, abs=1e-12)
    assert got.predictor.kappa == same.predictor.kappa  # no curvature read from the sign


@pytest.mark.timeout(10)
def test_no_curvature_is_read_over_a_sign():
    """On a straight, a branch's turned fit over a sign leaves the curvature estimate at 0."""
    predictor = CameraSteering(OURS, LC).predictor
    for _ in range(10):
        predictor.predict(0.0, 0.0, 0.05, 0.47)
    for angle in (0.3, 0.6, 0.9):  # the fit turning as a branch comes into the window
        predictor.predict(0.0, angle, 0.05, 0.47, plain=False)
    predictor.predict(0.0, 0.0, 0.05, 0.47)  # the sign behind: plain tape again
    assert predictor.kappa == 0.0


@pytest.mark.timeout(120)
def test_signs_1991_read_at_0_16_with_our_settings():
    """Every kind of sign on signs_1991 read at 0.16 m/s as the layout names it.

    P11 and P12 end their tape in a branch, which the turned fit steered the truck onto (read as
    P21 and P22) before the last plain frame's angle stood over a sign.
    """
    lay = load_layout(layout_path('signs_1991'))
    first: dict[str, int] = {}
    for i, sign in enumerate(lay.signs):
        first.setdefault(sign['type'], i)
    for kind, index in sorted(first.items()):
        lay = load_layout(layout_path('signs_1991'))
        sign = lay.signs[index]
        lay.start_path, lay.start_at = sign['path'], sign['at'] - 0.6
        world = WorldCore(lay, WorldParams(seed=7))
        reader = SignReader()
        route = RouteCore(RouteParams(vehicle='concic2', camera_speed=0.16, steering=OURS))
        Harness(world, [reader, route]).run(10.0, until=lambda r=reader: bool(r.signs))
        assert reader.signs == [kind], (kind, reader.signs)
        want = 'following' if 'straight' in sign['branches'] else 'no_branch'
        assert route.cam.reported_state() == want, (kind, route.cam.reported_state())
