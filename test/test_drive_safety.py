"""The CONCIC-II's safety supervisor, system 13 (Rajagopalan 1991, 6.3.11).

The PAL state machine on its own (agv_nodes/world/safety_pal.py), route following's software
checks on their own (agv_nodes/route_following/drive_safety.py), then each fault injected into
the whole truck in lock step on junction_1991 while a tape task runs: the motors go off, the
truck coasts to rest within the motor-off coast (plus the watchdog's 60 ms at cruise), the task
fails with cause drive_fault and the fault named, communications' report line says it, and the
truck stays at rest. E-stop and watchdog stay latched until the hardware reset; after it a new
task runs.
"""

import copy
import math

import pytest

from agv_nodes.harness import Harness, Link, submit, truck
from agv_nodes.records.ports import RecordWriter
from agv_nodes.route_following.drive_safety import DriveSafety, pal_fault
from agv_nodes.route_following.settings import DriveSafetyParams, RouteParams
from agv_nodes.world.safety_pal import SafetyPal
from agv_nodes.world.settings import Concic2Params, WorldParams

pytestmark = pytest.mark.timeout(60)

DT = 1.0 / WorldParams().sample_rate  # s, one world sample (340 Hz)
WATCHDOG = Concic2Params().watchdog  # s, the PAL's (test_hardware_cuts: the thesis's 60 ms)
CRUISE = 0.47  # m/s, route following's camera_speed
HEALTHY = {'state': 'ready', 'route_code': 2, 'estop': 0, 'watchdog': 0, 'over_voltage': 0,
           'controller_fault': 'none', 'encoder_fault': 'none', 'battery': 240, 'sample': 1}


def _run_pal(pal: SafetyPal, start: float, seconds: float, command: dict | None = None) -> float:
    """Step the PAL each sample from `start`, retriggering it every 10 ms with `command`."""
    now = start
    while now < start + seconds - 1e-9:
        now += DT
        if command is not None and round(now / DT) % 3 == 0:
            pal.command(command, now)
        pal.step(now)
    return now


GO = {'mode': 'wheel_speeds', 'enable': 1, 'left_speed': 470, 'right_speed': 470}


# -- the PAL (world side) ----------------------------------------------------------------------
@pytest.mark.timeout(10)
def test_pal_powers_the_amplifiers_after_both_start_up_tests():
    pal = SafetyPal(Concic2Params())
    assert (pal.state, pal.code, pal.powered) == ('reset', 0, False)
    _run_pal(pal, 0.0, 0.025)
    assert (pal.state, pal.code, pal.powered) == ('controllers_ok', 1, False)
    _run_pal(pal, 0.025, 0.025)
    assert (pal.state, pal.code, pal.powered) == ('ready', 2, True)  # 40 ms after the reset
    record = pal.record()
    assert (record['state'], record['route_code'], record['battery']) == ('ready', 2, 240)


@pytest.mark.timeout(10)
def test_pal_start_up_tests_fail_on_an_injected_fault():
    pal = SafetyPal(Concic2Params(controller_fault='right'))
    _run_pal(pal, 0.0, 0.5)
    assert (pal.state, pal.code, pal.controller, pal.powered) == ('fault', 6, 'right', False)
    pal = SafetyPal(Concic2Params(encoder_fault='left'))
    _run_pal(pal, 0.0, 0.5)
    assert (pal.state, pal.code, pal.encoder, pal.powered) == ('controllers_ok', 1, 'left',
                                                                False)
    pal.p.encoder_fault = 'none'  # mended: only a reset runs the test again
    _run_pal(pal, 0.5, 0.5)
    assert pal.state == 'controllers_ok'
    pal.hardware_reset(1.0)
    _run_pal(pal, 1.0, 0.1)
    assert pal.state == 'ready'


@pytest.mark.timeout(10)
def test_pal_watchdog_is_armed_by_the_first_command_and_latches():
    pal = SafetyPal(Concic2Params())
    now = _run_pal(pal, 0.0, 1.0)  # no command yet: the computer's loop has not started
    assert pal.state == 'ready'
    now = _run_pal(pal, now, 1.0, GO)
    assert pal.state == 'ready'
    pal.command(GO, now)  # the last one
    last = now
    while pal.state == 'ready':
        now += DT
        pal.step(now)
    assert WATCHDOG < now - last <= WATCHDOG + DT + 1e-9  # the first sample past it
    assert (pal.code, pal.watchdog) == (7, True)
    now = _run_pal(pal, now, 1.0, GO)  # commands again: still latched
    assert (pal.state, pal.powered) == ('fault', False)
    pal.hardware_reset(now)
    _run_pal(pal, now, 0.1, GO)
    assert (pal.state, pal.watchdog) == ('ready', False)


@pytest.mark.timeout(10)
def test_pal_estop_latches_through_a_reset_while_pressed():
    pal = SafetyPal(Concic2Params())
    now = _run_pal(pal, 0.0, 0.2, GO)
    pal.p.estop = True
    now = _run_pal(pal, now, DT, GO)
    assert (pal.state, pal.code, pal.estop, pal.powered) == ('fault', 4, True, False)
    pal.hardware_reset(now)  # the button still pressed: straight back to the fault
    now = _run_pal(pal, now, 0.2, GO)
    assert (pal.state, pal.estop) == ('fault', True)
    pal.p.estop = False  # released: still latched until the reset
    now = _run_pal(pal, now, 0.2, GO)
    assert pal.state == 'fault'
    pal.hardware_reset(now)
    _run_pal(pal, now, 0.1, GO)
    assert (pal.state, pal.estop) == ('ready', False)


@pytest.mark.timeout(10)
def test_pal_over_voltage_on_a_demand_beyond_full_speed():
    pal = SafetyPal(Concic2Params())
    now = _run_pal(pal, 0.0, 0.2, GO)
    full = round(pal.p.max_wheel_speed * 1000)
    pal.command({**GO, 'left_speed': full, 'right_speed': -full}, now)  # at the level: fine
    pal.command({**GO, 'enable': 0, 'left_speed': 2000}, now)  # motor off: the DAC is idle
    assert pal.state == 'ready'
    pal.command({**GO, 'right_speed': -(full + 1)}, now)
    assert (pal.state, pal.code, pal.over_voltage) == ('fault', 5, True)


# -- route following's checks ------------------------------------------------------------------
def _odometry(left_mm: int, right_mm: int) -> dict:
    return {'left_speed': 0, 'right_speed': 0, 'left_distance': left_mm,
            'right_distance': right_mm, 'sample': 0}


@pytest.mark.timeout(10)
def test_pal_faults_are_named_first_then_the_battery():
    assert pal_fault(HEALTHY, 22.0) == 'none'
    assert pal_fault({**HEALTHY, 'battery': 219}, 22.0) == 'battery_low'
    assert pal_fault({**HEALTHY, 'battery': 220}, 22.0) == 'none'
    assert pal_fault({**HEALTHY, 'estop': 1, 'watchdog': 1}, 22.0) == 'estop'
    assert pal_fault({**HEALTHY, 'watchdog': 1, 'over_voltage': 1}, 22.0) == 'watchdog'
    assert pal_fault({**HEALTHY, 'over_voltage': 1}, 22.0) == 'over_voltage'
    assert pal_fault({**HEALTHY, 'controller_fault': 'left'}, 22.0) == 'controller'
    assert pal_fault({**HEALTHY, 'encoder_fault': 'right'}, 22.0) == 'encoder_right'


@pytest.mark.timeout(10)
def test_encoder_check_names_the_silent_wheel_after_encoder_time():
    safety = DriveSafety(DriveSafetyParams())
    safety.drive_status(HEALTHY)
    left, now = 0, 0.0
    for _ in range(100):  # 1 s: the left wheel counts, the right one never does
        now += 0.01
        left += 4
        safety.odometry(_odometry(left, 7), (0.4, 0.4), True, now)
        if safety.fault != 'none':
            break
    assert safety.fault == 'encoder_right'
    assert now == pytest.approx(0.01 + DriveSafetyParams().encoder_time, abs=0.011)
    safety.clear()  # reload
    assert safety.fault == 'none'


@pytest.mark.parametrize('demand, motor_on, state', [
    ((0.4, 0.4), False, 'ready'),  # motor off: the wheels coast or stand
    ((0.02, 0.02), True, 'ready'),  # too slow a demand to count on a count
    ((0.4, 0.4), True, 'fault'),  # the PAL cut the amplifiers
])
@pytest.mark.timeout(10)
def test_encoder_check_only_where_the_wheels_must_turn(demand, motor_on, state):
    safety = DriveSafety(DriveSafetyParams())
    safety.drive_status({**HEALTHY, 'state': state})
    for k in range(200):
        safety.odometry(_odometry(5, 5), demand, motor_on, k * 0.01)
    assert safety.encoder == 'none'


# -- the whole truck ---------------------------------------------------------------------------
@pytest.fixture(scope='module')
def under_way() -> Harness:
    """junction_1991 at cruise on a 'tape for 5.0 m' task (copied by each test)."""
    h = truck('junction_1991', seed=1)
    h.run(0.2)
    assert h.world.pal.state == 'ready'
    submit(h, 'tape for 5.0 m')
    assert h.run(4.0, until=lambda: h.world.vehicle.state.speed > CRUISE - 0.005)
    return h


def _inject(h: Harness, fault: str) -> None:
    w = h.world
    if fault == 'estop':
        w.p.concic2.estop = True
    elif fault == 'watchdog':  # route following's steering commands stop reaching the servos
        h.links['steering_command'] = Link(drop=1.0)
    elif fault == 'controller':
        w.p.concic2.controller_fault = 'left'
    elif fault in ('encoder_left', 'encoder_right'):
        w.p.concic2.encoder_fault = fault.split('_')[1]
    elif fault == 'battery_low':
        w.p.concic2.battery_voltage = 21.5
    elif fault == 'over_voltage':  # one foreign demand beyond the full-speed level
        schema = h.codec['steering_command']
        h.inject('steering_command', RecordWriter(schema, 'none').pack(
            {'mode': 'wheel_speeds', 'enable': 1, 'left_speed': 1500, 'right_speed': 1500}))


# The motors off within: the PAL at once (E-stop, controller, DAC), its 60 ms watchdog, the
# next drive_status (50 ms) and route following's next pass (10 ms) for the battery, and the
# encoder check's encoder_time (0.3 s) after the count stops.
STATUS_PERIOD = 1.0 / WorldParams().drive_status_rate
ROUTE_PERIOD = RouteParams().period
ENCODER_TIME = DriveSafetyParams().encoder_time
MOTORS_OFF = {'estop': 2 * DT, 'controller': 2 * DT, 'over_voltage': 2 * DT,
              'watchdog': WATCHDOG + 2 * DT, 'battery_low': STATUS_PERIOD + ROUTE_PERIOD + 2 * DT,
              'encoder_left': ENCODER_TIME + 2 * ROUTE_PERIOD + 2 * DT,
              'encoder_right': ENCODER_TIME + 2 * ROUTE_PERIOD + 2 * DT}
WORDS = {'estop': 'estop', 'watchdog': 'watchdog', 'over_voltage': 'over voltage',
         'controller': 'controller', 'encoder_left': 'encoder left',
         'encoder_right': 'encoder right', 'battery_low': 'battery low'}


@pytest.mark.parametrize('fault', list(MOTORS_OFF))
def test_each_fault_stops_the_truck_and_fails_the_task_naming_it(under_way, fault):
    h = copy.deepcopy(under_way)
    w, st = h.world, h.world.vehicle.state
    speed, start, x0, y0 = st.speed, h.now, st.x, st.y
    assert speed == pytest.approx(CRUISE, abs=0.01) and w.vehicle.enable
    _inject(h, fault)
    assert h.run(1.0, until=lambda: not w.vehicle.enable)
    off = h.now - start
    assert off <= MOTORS_OFF[fault] + 1e-9, off
    assert h.run(1.0, until=lambda: st.speed == 0.0)
    coast = speed * speed / (2.0 * w.p.concic2.coast_deceleration)  # 42 mm from 0.47 m/s
    travelled = math.hypot(st.x - x0, st.y - y0)
    assert travelled <= speed * off + coast + 0.002, (travelled, off)
    assert h.now - start <= off + speed / w.p.concic2.coast_deceleration + 2 * DT
    h.run(0.2)
    executive, route = h.cores['executive'], h.cores['route_following']
    assert executive.report == {'state': 'failed', 'cause': 'drive_fault', 'subsystem': 'route',
                                'detail': fault}
    assert h.cores['communications'].notes.texts()[-1] == \
        f"task 1 'tape for 5.0 m': FAILED: drive fault (route): {WORDS[fault]}"
    assert h.cores['communications'].results[-1] == (1, 'failed', 'drive_fault')
    rest = (st.x, st.y)
    h.run(1.5)  # held: motor-off route command, no wheel demand
    assert st.speed == 0.0 and (st.x, st.y) == rest and not route.motor_on


def _stopped_by(fault: str, under_way: Harness) -> Harness:
    h = copy.deepcopy(under_way)
    _inject(h, fault)
    h.run(1.5)
    assert h.cores['executive'].report['detail'] == fault
    return h


def _new_task_runs(h: Harness, task_id: int) -> bool:
    submit(h, 'tape for 1.0 m')
    return h.run(3.0, until=lambda: h.cores['executive'].task_id == task_id
                 and h.cores['executive'].mode == 'running'
                 and h.world.vehicle.state.speed > 0.2)


@pytest.mark.parametrize('fault', ['estop', 'watchdog'])
def test_estop_and_watchdog_hold_until_the_hardware_reset(under_way, fault):
    h = _stopped_by(fault, under_way)
    w = h.world
    w.p.concic2.estop = False  # released (or the loop's commands back): the PAL stays latched
    h.links.pop('steering_command', None)
    h.run(0.5)
    assert (w.pal.state, w.pal.code) == ('fault', {'estop': 4, 'watchdog': 7}[fault])
    assert h.cores['route_following'].safety.fault == fault
    submit(h, 'tape for 1.0 m')  # a task before the reset fails at once
    h.run(0.5)
    assert h.cores['executive'].task_id == 2
    assert h.cores['executive'].report['detail'] == fault
    assert w.vehicle.state.speed == 0.0
    w.hardware_reset()
    h.run(0.2)
    assert w.pal.state == 'ready' and h.cores['route_following'].safety.fault == 'none'
    assert _new_task_runs(h, 3)
    assert h.cores['executive'].report['cause'] == 'none'


@pytest.mark.timeout(30)
def test_a_reset_with_the_estop_still_pressed_changes_nothing(under_way):
    h = _stopped_by('estop', under_way)
    h.world.hardware_reset()
    h.run(0.3)
    assert h.world.pal.state == 'fault' and not h.world.vehicle.enable


@pytest.mark.timeout(30)
def test_software_faults_clear_with_their_cause_no_reset_needed(under_way):
    """A software-detected stop is cleared by reloading the software (6.3.11): a new task."""
    h = _stopped_by('battery_low', under_way)
    h.world.p.concic2.battery_voltage = 24.0  # charged
    h.run(0.2)
    assert h.world.pal.state == 'ready'
    assert _new_task_runs(h, 2)
    h = _stopped_by('encoder_left', under_way)
    h.world.p.concic2.encoder_fault = 'none'  # the encoder mended
    assert _new_task_runs(h, 2)
    assert h.cores['executive'].report['cause'] == 'none'


@pytest.mark.timeout(30)
def test_drive_status_is_published_at_20_hz(under_way):
    h = copy.deepcopy(under_way)
    seen: list[float] = []
    h.taps.append(lambda record, raw, now: seen.append(now) if record == 'drive_status' else None)
    h.world.p.concic2.battery_voltage = 23.4
    h.run(1.0)
    assert len(seen) == 20
    fields = h.cores['route_following'].safety.status
    assert (fields['state'], fields['battery']) == ('ready', 234)
