"""Manual driving from cmd_vel, system 14 (Rajagopalan 1991, App. F.4 keypad mode), in lock step.

The world core, route following and a scripted executive (route_command mode manual), seeded;
a teleop stand-in hands route following a Twist every 0.1 s as a held key of
teleop_twist_keyboard would. The motion is judged by the world's ground truth (its own
kinematic CONCIC-II, wheel span from the world's parameters); the limits and the watchdog's
timeout are the declared parameter values.
"""

from __future__ import annotations

import copy
import math

import pytest

from agv_nodes.harness import Harness
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.manual_drive import wheel_speeds
from agv_nodes.route_following.settings import ManualParams, RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

pytestmark = pytest.mark.timeout(60)

KINEMATIC = Concic2Params(model='kinematic')
DT = 1.0 / WorldParams().sample_rate  # s, one world sample
ROUTE_PERIOD = RouteParams().period  # s, route following's loop (steering_command)
TIMEOUT = ManualParams().timeout  # s, the declared cmd_vel watchdog
TELEOP = 0.1  # s between Twists


class Exec:
    """A scripted executive: one route_command, changed by the test; keeps route_status."""

    node, period = 'executive', 0.05

    def __init__(self, mode: str = 'manual') -> None:
        self.command = {'mode': mode, 'srm_angle': 0, 'junction': 'straight', 'manoeuvre': 0,
                        'direction': 'forward', 'junction_number': 0, 'junction_wait': 0,
                        'leg': 1}
        self.status: dict = {}

    def on_record(self, record, fields, now):
        if record == 'route_status':
            self.status = fields

    def tick(self, now):
        return {'route_command': dict(self.command)}


def manual_truck(mode: str = 'manual', model: Concic2Params = KINEMATIC, **route: object
                 ) -> tuple[Harness, WorldCore, RouteCore, Exec]:
    world = WorldCore(load_layout(layout_path('junction_1991')),
                      WorldParams(seed=3, concic2=copy.deepcopy(model)))  # tests set faults
    params = RouteParams(vehicle='concic2')
    for name, value in route.items():
        setattr(params.manual, name, value)
    script, core = Exec(mode), RouteCore(params)
    h = Harness(world, [script, core], seed=3)
    h.run(0.1)  # the PAL's start-up tests (40 ms)
    return h, world, core, script


def teleop(h: Harness, route: RouteCore, seconds: float, linear: float, angular: float,
           **also: float) -> list[str]:
    """Send a Twist every TELEOP s for `seconds`; return route following's verdicts."""
    lin = (linear, also.get('y', 0.0), 0.0)
    ang = (0.0, 0.0, angular)
    verdicts = []
    for _ in range(round(seconds / TELEOP)):
        verdicts.append(route.on_twist(lin, ang, h.now))
        h.run(TELEOP)
    return verdicts


def measured(h: Harness, world: WorldCore, seconds: float = 1.0) -> tuple[float, float]:
    """Ground truth over `seconds` (the teleop still sending): speed (m/s) and yaw rate (rad/s)."""
    st = world.vehicle.state
    route = next(m.core for m in h.members if isinstance(m.core, RouteCore))
    twist = (route.manual.speed, route.manual.yaw_rate)
    x0, y0, h0, t0 = st.x, st.y, st.heading, h.now
    teleop(h, route, seconds, *twist)
    along = (st.x - x0) * math.cos(h0) + (st.y - y0) * math.sin(h0)
    turned = st.heading - h0
    # a chord of an arc: arc length = chord * (turned / 2) / sin(turned / 2)
    arc = math.hypot(st.x - x0, st.y - y0) * (
        1.0 if abs(turned) < 1e-9 else (turned / 2) / math.sin(turned / 2))
    return math.copysign(arc, along) / (h.now - t0), turned / (h.now - t0)


# -- the conversion (Eq. 5.13-5.14) -----------------------------------------------------------
@pytest.mark.timeout(10)
def test_wheel_speeds_are_eq_5_13_and_scaled_as_a_pair_past_full_speed():
    # V_L = V - psi' L / 2, V_R = V + psi' L / 2, L = 0.52 m (Table 6.1, the world's span)
    assert wheel_speeds(0.3, 0.5, 0.52, 1.14) == pytest.approx((0.17, 0.43), abs=1e-12)
    assert wheel_speeds(0.0, -1.0, 0.52, 1.14) == pytest.approx((0.26, -0.26), abs=1e-12)
    # 1.0 m/s at 2 rad/s wants 0.48 and 1.52 m/s: the pair scaled by 1.14 / 1.52
    assert wheel_speeds(1.0, 2.0, 0.52, 1.14) == pytest.approx((0.36, 1.14), abs=1e-12)


# -- driving the world --------------------------------------------------------------------------
@pytest.mark.parametrize('linear, angular', [(0.3, 0.5), (0.3, -0.5), (-0.2, 0.0), (0.0, 0.8)])
def test_a_twist_drives_the_truck_at_that_speed_and_yaw_rate(linear, angular):
    h, world, route, script = manual_truck()
    assert world.p.concic2.wheel_span == route.p.steering.wheel_span  # the same truck
    teleop(h, route, 3.0, linear, angular)  # the drive's 0.3 m/s^2 ramp is over by then
    speed, yaw_rate = measured(h, world)
    # the record carries each rim speed in whole mm/s: +-0.5 mm/s a wheel
    assert speed == pytest.approx(linear, abs=0.0006)
    assert yaw_rate == pytest.approx(angular, abs=1e-3 / world.p.concic2.wheel_span + 1e-4)
    assert script.status['state'] == 'manual'
    assert route.manual.refused == {} and route.manual.taken == 40


def test_twists_beyond_the_limits_are_clipped_to_the_declared_ones():
    h, world, route, _ = manual_truck()
    teleop(h, route, 4.0, 5.0, 0.0)
    speed, _ = measured(h, world)
    assert speed == pytest.approx(ManualParams().max_speed, abs=0.0006)
    h, world, route, _ = manual_truck()
    teleop(h, route, 3.0, 0.0, -9.0)
    _, yaw_rate = measured(h, world)
    assert yaw_rate == pytest.approx(-ManualParams().max_yaw_rate, abs=0.002)
    assert route.manual.clipped == 30  # the teleop's; measured() resends the clipped twist


# -- the supervisor -----------------------------------------------------------------------------
@pytest.mark.parametrize('model', [KINEMATIC, Concic2Params()], ids=['kinematic', 'dynamic'])
def test_silent_cmd_vel_stops_the_truck_after_the_timeout_and_the_next_one_drives(model):
    h, world, route, script = manual_truck(model=model)
    st = world.vehicle.state
    teleop(h, route, 3.0, 0.4, 0.0)
    last = h.now - TELEOP  # the last Twist
    assert st.speed == pytest.approx(0.4, abs=0.002) and world.vehicle.enable
    # still driven until the timeout, the motors cut within a loop pass and a sample after it
    assert not h.run(last + TIMEOUT - ROUTE_PERIOD - h.now, until=lambda: not world.vehicle.enable)
    assert h.run(2 * ROUTE_PERIOD + 2 * DT, until=lambda: not world.vehicle.enable)
    cut, x_cut = h.now, st.x
    assert cut - last == pytest.approx(TIMEOUT, abs=ROUTE_PERIOD + 2 * DT)
    assert h.run(2.0, until=lambda: st.speed == 0.0)
    coast = 0.4 ** 2 / (2.0 * world.p.concic2.coast_deceleration)
    assert 0.0 < st.x - x_cut <= coast + 0.002
    assert route.manual.watchdog_stops == 1 and not route.motor_on
    h.run(1.0)
    assert st.speed == 0.0 and script.status['state'] == 'manual'  # held, still in manual mode
    teleop(h, route, 2.0, 0.2, 0.0)  # a new command drives again
    assert st.speed == pytest.approx(0.2, abs=0.002)


def test_estop_wins_over_cmd_vel_and_every_command_after_it_is_refused():
    h, world, route, script = manual_truck()
    st = world.vehicle.state
    teleop(h, route, 3.0, 0.4, 0.0)
    world.p.concic2.estop = True
    # the PAL cuts the amplifiers at once; route following stops asking within the next
    # drive_status (20 Hz) and a pass of its loop, not by the watchdog a second on
    assert h.run(1.0 / WorldParams().drive_status_rate + ROUTE_PERIOD + 2 * DT,
                 until=lambda: not route.motor_on)
    verdicts = teleop(h, route, 3.0, 0.4, 0.0)  # the operator holds the key down
    assert st.speed == 0.0 and not world.vehicle.enable
    assert not route.motor_on and route.steering_command()['enable'] == 0
    # the drive_status after the cut (20 Hz) tells route following within a Twist or two
    assert set(verdicts) == {'drive_fault'}
    assert route.manual.refused['drive_fault'] == verdicts.count('drive_fault')
    assert script.status['state'] == 'drive_fault' and script.status['drive_fault'] == 'estop'


def test_leaving_manual_mode_stops_the_truck_and_refuses_later_twists():
    h, world, route, script = manual_truck()
    st = world.vehicle.state
    teleop(h, route, 3.0, 0.4, 0.0)
    script.command['mode'] = 'idle'
    assert h.run(0.1, until=lambda: not world.vehicle.enable)
    verdicts = teleop(h, route, 2.0, 0.4, 0.0)
    assert set(verdicts) == {'not_manual'} and route.manual.refused['not_manual'] == 20
    assert st.speed == 0.0 and script.status['state'] == 'idle'


@pytest.mark.parametrize('mode', ['idle', 'camera'])
def test_cmd_vel_outside_manual_mode_is_refused_counted_and_never_acted_on(mode):
    h, world, route, _ = manual_truck(mode)
    st = world.vehicle.state
    x0, y0, h0 = st.x, st.y, st.heading
    if mode == 'camera':
        h.run(2.0)  # the tape leg under way: the Twist must not bend it
        assert st.speed > 0.3
    verdicts = teleop(h, route, 2.0, 0.0, 1.0)
    assert set(verdicts) == {'not_manual'} and route.manual.refused == {'not_manual': 20}
    assert route.manual.taken == 0
    if mode == 'idle':
        assert (st.x, st.y, st.heading) == (x0, y0, h0) and not world.vehicle.enable
    else:  # on the straight tape, heading along it, not spun at 1 rad/s
        assert abs(st.heading - h0) < 0.05 and route.state in ('following', 'sign')


def test_a_twist_that_is_no_number_or_not_planar_is_refused_and_the_last_one_stands():
    h, world, route, _ = manual_truck()
    teleop(h, route, 3.0, 0.3, 0.0)
    assert route.on_twist((math.nan, 0.0, 0.0), (0.0, 0.0, 0.0), h.now) == 'not_finite'
    assert route.on_twist((0.3, 0.0, 0.0), (0.0, 0.0, math.inf), h.now) == 'not_finite'
    assert route.on_twist((0.3, 0.2, 0.0), (0.0, 0.0, 0.0), h.now) == 'not_planar'
    assert route.on_twist((0.3, 0.0, 0.0), (0.1, 0.0, 0.0), h.now) == 'not_planar'
    assert route.manual.refused == {'not_finite': 2, 'not_planar': 2}
    assert route.wheels == pytest.approx((0.3, 0.3))
    assert [n.text for n in route.notes.recent if 'refused' in n.text] == [
        'cmd_vel refused (not_finite)', 'cmd_vel refused (not_planar)']


def test_the_radio_stop_holds_the_truck_against_a_held_key_and_stays_stopped():
    # The world's power cut (concic2_dynamics: the chips off while hw/radio_stop is true),
    # told to route following in drive_status (radio_stop): a drive fault it names, latched
    # until the mode is left: released, the held key does not drive the truck off.
    h, world, route, _ = manual_truck()
    st = world.vehicle.state
    teleop(h, route, 3.0, 0.4, 0.0)
    h.set_radio_stop(True)
    teleop(h, route, 1.0, 0.4, 0.0)  # coasting to rest from 0.4 m/s takes 0.08 s
    x = st.x
    teleop(h, route, 3.0, 0.4, 0.0)
    assert st.speed == 0.0 and st.x == x
    assert route.safety.fault == 'radio_stop' and not route.motor_on
    h.set_radio_stop(False)
    verdicts = teleop(h, route, 3.0, 0.4, 0.0)
    assert set(verdicts) == {'drive_fault'} and st.speed == 0.0 and st.x == x
