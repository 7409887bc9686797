"""Route following: wire offset from the coils, lost wire, SRM landing, camera guidance."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest

from agv_nodes.harness import Harness
from agv_nodes.route_following.camera_guidance import (
    CameraSteering,
    ImageAnalyser,
    Measurement,
    Validity,
    runs_of,
)
from agv_nodes.route_following.core import RouteCore, wire_offset
from agv_nodes.route_following.settings import ImageParams, RouteParams, SteeringParams
from agv_nodes.traction.core import TractionCore
from agv_nodes.world.camera import BinaryCamera
from agv_nodes.world.core import WorldCore
from agv_nodes.world.guide_wire import GuideWirePickup
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import CameraParams, Concic2Params, PickupParams, WorldParams

# Camera-mode runs here time and place the truck as the kinematic CONCIC-II drives (the default
# is the dynamic model): pinned, not given looser tolerances.
KINEMATIC = Concic2Params(model='kinematic')


@pytest.mark.parametrize('offset', [-0.35, -0.15, -0.05, -0.01, 0.0, 0.02, 0.09, 0.2, 0.3])
def test_wire_offset_from_the_coils_is_unambiguous(offset):
    lay = load_layout(layout_path('straight_track'))
    pickup = GuideWirePickup(PickupParams(noise=0.0), [lay.paths['A']], random.Random(0))
    left, right = pickup.coils(10.0, -offset, 0.0)  # sensor point `offset` right of the wire
    est = wire_offset(left, right, 0.20, 0.08, pickup.p.nominal)
    assert est == pytest.approx(offset, abs=0.004 + 0.02 * abs(offset))


class Exec:
    """A stand-in executive: drives, and commands route following."""

    node = 'executive'
    period = 0.05

    def __init__(self, demand: int, mode: str = 'follow_wire') -> None:
        self.demand, self.mode, self.manoeuvre, self.angle = demand, mode, 0, 0
        self.states: list[str] = []

    def on_record(self, record, fields, now):
        if record == 'route_status' and (not self.states or self.states[-1] != fields['state']):
            self.states.append(fields['state'])

    def tick(self, now):
        return {'traction_command': dict(manual=0, manual_speed=0, reverse=0,
                                         demand=self.demand if now > 0.3 else 0,
                                         executive_priority=0),
                'route_command': dict(mode=self.mode, srm_angle=self.angle,
                                      junction='straight', manoeuvre=self.manoeuvre)}


def test_follows_the_demo_wire_within_1_cm_and_reports_lost_at_its_end():
    world = WorldCore(load_layout(layout_path('demo_1983')), WorldParams(seed=4))
    ex, route = Exec(55), RouteCore()
    h = Harness(world, [ex, TractionCore(), route])
    worst = 0.0
    while route.state != 'lost' and h.now < 60:
        h.step()
        if h.now > 3 and world.sample % 17 == 0:
            sx, sy = world.vehicle.sensor_point
            worst = max(worst, abs(world.nearest_path_offset(sx, sy)))
    assert worst < 0.010  # the goal here: the wire held to +-1 cm (straights and the arc)
    assert route.state == 'lost' and ex.states[-1] == 'lost'  # wire A ends at x = 6
    sx, _sy = world.vehicle.sensor_point
    assert sx < 6.0


def test_srm_leaves_wire_a_and_lands_on_wire_b():
    world = WorldCore(load_layout(layout_path('demo_1983')), WorldParams(seed=4))
    ex, route = Exec(27), RouteCore()
    h = Harness(world, [ex, TractionCore(), route])
    started = None
    while h.now < 120:
        h.step()
        sx, sy = world.vehicle.sensor_point
        if started is None and sy > 4.5 and sx < 8.5:  # L1 on A's west leg
            ex.mode, ex.manoeuvre, ex.angle, started = 'srm', 1, 15, h.now
        if started is not None and h.now > started + 18:
            break
    assert ex.states[-4:] == ['following', 'srm_running', 'wire_found', 'following']
    sx, sy = world.vehicle.sensor_point
    assert abs(sy - 4.0) < 0.01  # on wire B (y = 4) within 1 cm
    assert route.status()['manoeuvre'] == 1


def test_srm_that_finds_nothing_ends_lost():
    world = WorldCore(load_layout(layout_path('straight_track')), WorldParams(seed=4))
    ex, route = Exec(27), RouteCore()
    h = Harness(world, [ex, TractionCore(), route])
    h.run(4.0)
    ex.mode, ex.manoeuvre, ex.angle = 'srm', 1, 20
    h.run(20.0)
    assert route.state == 'lost'



def _feed(route: RouteCore, t: float, until: float, coil: int, speed: int,
          wire: bool = True) -> list[str]:
    """Drive the core at 100 Hz (odometry, maybe a pickup sample, a tick): the states sent."""
    sent = []
    while t < until - 1e-9:
        t += 0.01
        route.on_record('wheel_odometry', {'left_speed': speed, 'right_speed': speed,
                                           'left_distance': 0, 'right_distance': 0}, t)
        if wire:
            route.on_record('guide_wire', {'left_coil': coil, 'right_coil': coil}, t)
        out = route.tick(t)
        if 'route_status' in out:
            sent.append(out['route_status']['state'])
    return sent


def test_a_stalled_pickup_at_rest_is_lost_then_rearmed_when_the_wire_returns():
    route = RouteCore()
    route.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                      'junction': 'straight', 'manoeuvre': 0}, 0.0)
    assert _feed(route, 0.0, 0.5, 700, 0)[-1] == 'following'
    # The pickup stream stalls (no samples) with the truck standing: LOST goes out.
    assert 'lost' in _feed(route, 0.5, 0.7, 700, 0, wire=False)
    assert route.steering_command()['angle'] == 0
    # Samples again, truck at rest: following once lost_samples strong samples have come.
    states = _feed(route, 0.7, 0.8, 700, 0)
    assert route.state == 'following' and states[-1] == 'following'


def test_lost_holds_while_the_truck_moves_and_while_the_wire_is_weak():
    route = RouteCore()
    route.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                      'junction': 'straight', 'manoeuvre': 0}, 0.0)
    _feed(route, 0.0, 0.5, 700, 600)
    assert 'lost' in _feed(route, 0.5, 0.7, 50, 600)  # wire gone under a moving truck
    _feed(route, 0.7, 2.0, 700, 600)  # back, but the truck still rolls: no re-arm
    assert route.state == 'lost' and route.steering_command()['angle'] == 0
    _feed(route, 2.0, 3.0, 50, 0)  # at rest, but no wire
    assert route.state == 'lost'
    _feed(route, 3.0, 3.2, 700, 0)  # at rest on the wire
    assert route.state == 'following'


def test_the_integral_holds_while_the_truck_waits_at_rest():
    """A truck standing a few mm off the wire for minutes keeps its steering where it was.

    Integrating at rest wound the law up to full lock while a fleet's truck waited at a stop
    (2 mm for 100 s); it set off steering hard and lost the wire on the next curve.
    """
    route = RouteCore()
    route.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                      'junction': 'straight', 'manoeuvre': 0}, 0.0)
    left, right = 760, 700  # the wire a little to one side of the pickup
    t = 0.0
    for _ in range(100):
        t += 0.01
        route.on_record('wheel_odometry', {'left_speed': 0, 'right_speed': 0,
                                           'left_distance': 0, 'right_distance': 0}, t)
        route.on_record('guide_wire', {'left_coil': left, 'right_coil': right}, t)
        route.tick(t)
    first = route.steering_command()['angle']
    assert first != 0  # the proportional part steers toward the wire
    for _ in range(30000):  # 300 s more at rest
        t += 0.01
        route.on_record('wheel_odometry', {'left_speed': 0, 'right_speed': 0,
                                           'left_distance': 0, 'right_distance': 0}, t)
        route.on_record('guide_wire', {'left_coil': left, 'right_coil': right}, t)
        route.tick(t)
    assert route.steering_command()['angle'] == first


# -- camera ---------------------------------------------------------------------------------
def test_run_length_table():
    row = np.zeros(128, dtype=np.uint8)
    row[20:25] = row[40:65] = row[84:109] = 1  # the example of Rajagopalan 1991, Table 4.1
    assert runs_of(row) == [(20, 5), (40, 25), (84, 25)]


@pytest.mark.parametrize('offset, angle', [(0.0, 0.0), (0.03, 0.0), (-0.06, 5.0), (0.05, -8.0)])
def test_line_fit_recovers_the_tape_within_2_mm(offset, angle):
    lay = load_layout(layout_path('tape_1991'))
    tape = lay.paths['circle']
    cam = BinaryCamera(CameraParams(specks=8), [tape], np.random.default_rng(3))
    x, y, h = tape.pose_at(4.0)
    cx, cy = x + math.sin(h) * offset, y - math.cos(h) * offset
    heading = h + math.radians(angle)
    frame = cam.render(cx, cy, heading)  # with noise specks below the 16 px filter...
    analyser = ImageAnalyser(ImageParams(min_run=8))  # ...30 mm tape is ~15 px wide
    m = analyser.analyse(frame)
    eps_d, eps_theta = cam.truth(cx, cy, heading)
    assert m.validity is Validity.NORMAL
    assert m.eps_d == pytest.approx(eps_d, abs=0.002)
    assert math.degrees(m.eps_theta) == pytest.approx(math.degrees(eps_theta), abs=3.0)


def test_absent_four_frames_stops_saturated_holds():
    steer = CameraSteering(SteeringParams())
    good = Measurement(0.01, 0.0, Validity.NORMAL, 15, 64, False, False)
    absent = Measurement(0.0, 0.0, Validity.ABSENT, 0, 0, False, False)
    dark = Measurement(0.0, 0.0, Validity.SATURATED, 0, 0, False, False)
    held = steer.update(good, 0.05)
    assert steer.update(dark, 0.05) == held
    assert [steer.update(absent, 0.05) is None for _ in range(4)] == [False, False, False, True]


def test_wheel_speeds_eq_5_15_5_16():
    steer = CameraSteering(SteeringParams())
    left, right = steer.wheel_speeds(0.5, math.radians(10))
    assert right > left and (left + right) / 2 == pytest.approx(0.5)
    p = steer.p
    yaw = 0.5 * math.tan(math.radians(10)) / (p.caster_distance + p.caster_trail * (
        1 - math.cos(math.radians(10))))
    assert (right - left) / p.wheel_span == pytest.approx(yaw)


class CameraExec:
    node = 'executive'
    period = 0.05

    def on_record(self, *args):
        return None

    def tick(self, now):
        return {'route_command': dict(mode='camera', srm_angle=0, junction='straight',
                                      manoeuvre=0)}


@pytest.mark.parametrize('law, gain_i, limit_mm', [('p', 0.0, 60.0), ('pi', 0.07, 3.0)])
def test_camera_guidance_follows_the_circle(law, gain_i, limit_mm):
    world = WorldCore(load_layout(layout_path('tape_1991')), WorldParams(seed=2))
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=0.47,
                                  steering=SteeringParams(law=law, gain_i=gain_i)))
    h = Harness(world, [CameraExec(), route])
    h.run(25.0)
    errors = []
    for _ in range(10):  # the mean over 5 s, as route_bench measures it (PI: 1.1-1.5 mm)
        h.run(0.5)
        errors.append(abs(world.nearest_path_offset(*world.vehicle.sensor_point)))
    assert 1000 * sum(errors) / len(errors) < limit_mm
    assert route.state == 'following' and world.vehicle.state.speed > 0.4


class SignWatcher(CameraExec):
    """Collects the branch flags route_status carries when a road sign has been passed."""

    def __init__(self) -> None:
        self.signs: list[str | None] = []
        self._in_sign = False

    def on_record(self, record, fields, now):
        from agv_nodes.route_following.camera_guidance import sign_name

        if record != 'route_status':
            return None
        if fields['state'] == 'sign':
            self._in_sign = True
        elif self._in_sign:
            self._in_sign = False
            self.signs.append(sign_name(fields['sign_left'], fields['sign_right'],
                                        fields['sign_straight']))
        return None


@pytest.mark.parametrize('speed', [0.16, 0.47, 0.79])
def test_road_signs_decoded_at_every_junction(speed):
    """Rajagopalan 1991, 4.3: a width jump flags a sign, edge columns the branches (100 %)."""
    lay = load_layout(layout_path('tape_1991'))
    world = WorldCore(lay, WorldParams(seed=5, concic2=KINEMATIC))
    watcher = SignWatcher()
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed))
    h = Harness(world, [watcher, route])
    h.run(lay.paths['circle'].length / speed + 2.0)
    assert watcher.signs == [s['type'] for s in lay.signs]
    assert route.state == 'following'


class JunctionExec(CameraExec):
    """A scripted executive (Rajagopalan 1991, App. F.7: one decision per junction).

    It logs route states.
    """

    def __init__(self, junction: str) -> None:
        self.junction = junction
        self.states: list[str] = []

    def on_record(self, record, fields, now):
        if record == 'route_status' and (not self.states or self.states[-1] != fields['state']):
            self.states.append(fields['state'])
        return None

    def tick(self, now):
        return {'route_command': dict(mode='camera', srm_angle=0, junction=self.junction,
                                      manoeuvre=0)}


def _junction_run(layout, junction: str, seconds: float, speed: float = 0.47):
    # How far along the branch in `seconds`: the kinematic model's pace through the turn.
    world = WorldCore(layout, WorldParams(seed=3, concic2=KINEMATIC))
    script = JunctionExec(junction)
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed))
    h = Harness(world, [script, route])
    spin_at = None
    while h.now < seconds:
        h.step()
        if route.turn_phase == 'spin' and spin_at is None:
            s = world.vehicle.state
            spin_at = (s.x, s.y)
    return world, route, script, spin_at


@pytest.mark.parametrize('junction, heading, branch', [('left', 90.0, 'sign0_left'),
                                                        ('right', -90.0, 'sign0_right')])
def test_junction_choice_turns_onto_the_branch(junction, heading, branch):
    """Rajagopalan 1991, App. F.6: slow down at the sign, stop over the crossing, turn, follow.

    The vehicle stops with its axle over the crossing.
    """
    lay = load_layout(layout_path('junction_1991'))
    world, route, script, spin_at = _junction_run(lay, junction, 18.0)
    junction_xy = lay.paths['main'].pose_at(3.0)[:2]
    assert spin_at is not None and math.dist(spin_at, junction_xy) < 0.03
    assert script.states[:4] == ['following', 'sign', 'turning', 'following']
    s = world.vehicle.state
    assert math.degrees(s.heading) == pytest.approx(heading, abs=2.0)
    assert abs(s.y) > 1.0 and s.speed > 0.4  # well along the branch, at cruise
    along, off, _h = lay.paths[branch].project(*world.vehicle.sensor_point)
    assert abs(off) < 0.005 and along > 1.0  # the PI law on the branch (bench: 1-4 mm)
    assert route.state == 'following'


def test_straight_on_at_the_junction_keeps_to_the_main_tape():
    lay = load_layout(layout_path('junction_1991'))
    world, route, script, spin_at = _junction_run(lay, 'straight', 11.0)
    s = world.vehicle.state
    assert spin_at is None and 'turning' not in script.states
    assert s.x > 4.0 and abs(s.y) < 0.005 and abs(math.degrees(s.heading)) < 1.0
    assert route.state == 'following'


def test_a_branch_the_sign_does_not_offer_stops_the_vehicle(tmp_path):
    """A scripted branch the sign does not offer stops the vehicle.

    Rajagopalan 1991, App. F.7: "If a scripted option is not available on the floor, the vehicle
    stops".
    """
    text = layout_path('junction_1991').read_text().replace('type: R2', 'type: P22')
    (tmp_path / 'junction_1991.yaml').write_text(text)
    lay = load_layout(tmp_path / 'junction_1991.yaml')
    world, route, script, _spin = _junction_run(lay, 'left', 12.0)
    s = world.vehicle.state
    assert route.state == 'no_branch' and script.states[-1] == 'no_branch'
    # Stopped once the camera had passed the crossing, the axle short of it.
    assert abs(s.speed) < 0.01 and 2.2 < s.x < 3.0
    assert 'turning' not in script.states


def test_a_turn_whose_odometry_stops_ends_at_rest():
    """Safety: a spin whose wheel odometry falls silent mid-turn does not go on for ever.

    The spin ends by wheel odometry; if that falls silent the vehicle stops at turn_timeout
    (motors off as for a lost tape).
    """
    from agv_nodes.harness import Link

    lay = load_layout(layout_path('junction_1991'))
    world = WorldCore(lay, WorldParams(seed=3))
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=0.47))
    h = Harness(world, [JunctionExec('left'), route])
    while route.turn_phase != 'spin' and h.now < 15.0:
        h.step()
    assert route.turn_phase == 'spin'
    h.links['wheel_odometry'] = Link(drop=1.0)  # the encoders' records stop arriving
    h.run(route.p.turning.turn_timeout + 3.0)
    s = world.vehicle.state
    assert route.state == 'lost' and not route.motor_on
    assert abs(s.speed) < 0.005 and abs(s.yaw_rate) < 0.005
