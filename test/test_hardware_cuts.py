"""The world's hardware safety paths, each tested with no software cut to hide behind.

The radio stop (hw/radio_stop) and the bumper open the drive's power in the world (Baker 1983:
the radio-control stop in the drive's safety circuit; the bumper, modern, wired as it is), and
the CONCIC-II's safety PAL cuts its amplifiers when steering commands stop for 60 ms
(Rajagopalan 1991, 6.3.11). Traction also cuts the armature in software on a radio stop or a
bumper, so a test through traction's auto mode would pass with the world's cut gone. Here the
drive records keep asking for speed: written straight to the world core, or by traction in
manual mode, which bypasses the radio stop and the bumper by design (GETREF, App. B.2.2); the
CONCIC-II's route following never reads the radio stop at all. Each test fails when its one
hardware path is removed.

Expected values are worked out here from the declared parameters (agv_nodes/world/
parameters.yaml, read as a file): with the drive's power cut only friction acts, so the truck
is at rest within its speed over the friction deceleration (Coulomb drivetrain and rolling
resistance alone, a lower bound: viscous friction only adds to it).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from agv_nodes.harness import Harness, Link, submit, truck
from agv_nodes.records.ports import RecordReader
from agv_nodes.traction.core import TractionCore
from agv_nodes.traction.settings import TractionParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import WorldParams

pytestmark = pytest.mark.timeout(60)

PACKAGE = Path(__file__).resolve().parents[1] / 'agv_nodes'
G = 9.81
LB = 0.45359237  # kg
# Rajagopalan 1991, 6.3.11: the safety supervisor cuts the motors on a "watchdog timeout > 60 ms".
PAL_WATCHDOG = 0.060


def declared(package: str, section: str) -> dict[str, Any]:
    """Return the declared defaults of one section of a package's parameters.yaml."""
    text = (PACKAGE / package / 'parameters.yaml').read_text(encoding='utf-8')
    return {name: entry['default'] for name, entry in yaml.safe_load(text)[section].items()
            if isinstance(entry, dict)}


WORLD = declared('world', 'WorldParams')
ELECTRUK = declared('world', 'ElectrukParams')
CONCIC2 = declared('world', 'Concic2Params')
SAMPLE = 1.0 / WORLD['sample_rate']  # s, one world step


def electruk_friction_deceleration() -> float:
    """m/s^2 the Electruk loses with its drive unpowered (Coulomb terms only: a lower bound)."""
    p = ELECTRUK
    mass = p['mass'] + p['payload']
    coulomb = (p['motors'] * p['drivetrain_friction'] * p['gear_ratio'] / p['wheel_radius']
               + p['rolling_resistance'] * mass * G)
    return coulomb / (mass * p['inertia_factor'])


def concic2_friction_deceleration() -> float:
    """m/s^2 a wheel of the dynamic CONCIC-II loses with its armatures open (lower bound).

    Rajagopalan 1991, App. G and B.3-B.5 as the model's docstring gives them: each drive
    wheel's motor Coulomb friction T_f through the gear and its rolling resistance k1 N (N =
    W/4), over the heavier of the two modes per wheel: the mass and the yaw inertia over the
    half span squared, each with both rotors' inertia reflected to the rims. The casters'
    rolling and side friction only add to it.
    """
    n_r = 9.9 / 0.075  # gear over wheel radius (Table B.3)
    mass = (273.5 + 250.0) * LB  # Table B.1 and the experiments' 250 lb payload (7.3.2)
    rotors = 2.0 * n_r * n_r * 0.002  # J_m (Eq. B.12)
    half = CONCIC2['wheel_span'] / 2.0
    yaw = 22.2 + 250.0 * LB * 0.277 ** 2  # unloaded [D] and the payload's gyration [A]
    coulomb = 2.0 * (0.486 * n_r + 0.007 * mass * G / 4.0)  # T_f [D], k1 (Eq. G.45)
    return coulomb / max(mass + rotors, yaw / half ** 2 + rotors)


# -- the Electruk: drive records straight to the world -------------------------------------------
class DriveBox:
    """Writes traction_drive every 10 ms, the watchdog count running: traction's cut is absent."""

    def __init__(self, world: WorldCore, duty: int, forward: bool) -> None:
        self.world, self.count = world, 0
        self.sent = -1.0  # when the last record went (its count a new one)
        self.fields = {'armature_duty': duty, 'field_duty': 90, 'armature_enable': 1,
                       'field_enable': 1, 'field_forward': int(forward), 'contactor': 1,
                       'watchdog': 0}

    def run(self, seconds: float) -> None:
        w = self.world
        for _ in range(round(seconds / SAMPLE)):
            if w.sample % 3 == 0:  # every 3rd sample, near traction's 100 Hz loop
                self.count = (self.count + 1) & 0xFF
                self.sent = w.time
                w.on_record('traction_drive', {**self.fields, 'watchdog': self.count}, w.time)
            w.step()


def _electruk(forward: bool) -> tuple[WorldCore, DriveBox]:
    world = WorldCore(load_layout(layout_path('straight_track')), WorldParams(seed=3))
    box = DriveBox(world, 40, forward)
    box.run(4.0)
    speed = world.vehicle.state.speed
    assert (speed > 0.3) if forward else (speed < -0.3), speed
    assert world.vehicle.pushing and world.vehicle.current > 1.0
    return world, box


def _assert_electruk_cut(world: WorldCore, box: DriveBox) -> None:
    """Check: power off the next sample, the truck at rest within friction's time."""
    v = world.vehicle
    v0, i0 = abs(v.state.speed), v.current
    box.run(SAMPLE)
    assert not v.pushing  # the contactor circuit is open: no drive torque from here on
    # The armature current freewheels away through the diode with L/R: 1 % of it is left
    # after ln(100) time constants (one more sample for the step it was cut in).
    tau = ELECTRUK['armature_inductance'] / ELECTRUK['armature_resistance']
    box.run(math.log(100.0) * tau)
    assert v.current <= 0.01 * i0
    rest = v0 / electruk_friction_deceleration()
    start = world.time
    box.run(rest + SAMPLE)
    assert v.state.speed == 0.0, (v.state.speed, world.time - start, rest)
    box.run(1.0)  # the records still ask for 40 %: the truck stays put
    assert v.state.speed == 0.0 and v.current == 0.0


@pytest.mark.parametrize('forward', [True, False], ids=['forward', 'reverse'])
def test_radio_stop_cuts_the_electruk_drive_in_the_world(forward):
    world, box = _electruk(forward)
    world.set_radio_stop(True)
    _assert_electruk_cut(world, box)
    world.set_radio_stop(False)  # released: the same records drive it again
    box.run(1.0)
    assert abs(world.vehicle.state.speed) > 0.1 and world.vehicle.pushing


@pytest.mark.parametrize('forward', [True, False], ids=['forward', 'reverse'])
def test_bumper_cuts_the_electruk_drive_until_the_reset(forward):
    world, box = _electruk(forward)
    world.bump()
    assert [e['event'] for e in world.events] == ['collision']
    _assert_electruk_cut(world, box)
    world.hardware_reset()  # the bumper frees: the same records drive it again
    box.run(1.0)
    assert abs(world.vehicle.state.speed) > 0.1 and world.vehicle.pushing


# -- the Electruk: traction in manual mode (its software cut bypassed by design) ------------------
class ManualBox:
    """Stands in for the executive: arms traction (00H, then a demand), then drives manually."""

    node, period = 'executive', 0.05

    def __init__(self, speed: int, reverse: int) -> None:
        self.speed, self.reverse, self.passes = speed, reverse, 0

    def on_record(self, record: str, fields: dict, now: float) -> None:
        return None

    def tick(self, now: float) -> dict[str, dict[str, int]]:
        self.passes += 1
        manual = self.passes > 4  # 00H twice, a demand twice, then byte 1 is the demand
        return {'traction_command': {
            'manual': int(manual), 'manual_speed': self.speed if manual else 0,
            'reverse': self.reverse if manual else 0, 'demand': 0 if self.passes <= 2 else 30,
            'executive_priority': 0}}


def _manual(control: str, reverse: int) -> tuple[Harness, TractionCore]:
    traction = TractionCore(TractionParams(control=control))
    world = WorldCore(load_layout(layout_path('straight_track')), WorldParams(seed=3))
    # byte 1 = 1 | speed << 1 | reverse << 7 taken whole as a signed byte (App. B.2.2):
    # 20 forward is 41 %, 50 reverse 229 - 256 = -27 %
    h = Harness(world, [traction, ManualBox(50 if reverse else 20, reverse)])
    h.run(6.0)
    assert traction.source == 'manual' and not traction.tripped
    speed = world.vehicle.state.speed
    assert (speed < -0.15) if reverse else (speed > 0.3), speed
    return h, traction


def _drive_records(h: Harness) -> list[dict]:
    seen: list[dict] = []
    reader = RecordReader(h.codec['traction_drive'], 'e2e')
    h.taps.append(lambda record, raw, now: seen.append(reader.accept(raw, round(now * 1e9)))
                  if record == 'traction_drive' else None)
    return seen


def _assert_cut_under_manual(h: Harness) -> None:
    drives = _drive_records(h)
    v = h.world.vehicle
    v0 = abs(v.state.speed)
    h.run(SAMPLE)
    assert not v.pushing
    h.run(v0 / electruk_friction_deceleration() + SAMPLE)
    assert v.state.speed == 0.0
    h.run(1.0)
    assert v.state.speed == 0.0 and v.current == 0.0
    # traction kept the armature on all along: the world's cut was the only one
    assert len(drives) > 100 and all(d is not None and d['armature_enable'] and d['contactor']
                                     for d in drives)


@pytest.mark.parametrize('control', ['open_loop_1983', 'closed_loop'])
@pytest.mark.parametrize('reverse', [0, 1], ids=['forward', 'reverse'])
def test_radio_stop_stops_a_manually_driven_electruk(control, reverse):
    h, traction = _manual(control, reverse)
    h.set_radio_stop(True)
    assert traction.radio and traction.source == 'manual'
    _assert_cut_under_manual(h)
    assert traction.source == 'manual' and traction.status()['radio_stop'] == 1


@pytest.mark.parametrize('control', ['open_loop_1983', 'closed_loop'])
def test_bumper_stops_a_manually_driven_electruk(control):
    h, traction = _manual(control, 0)
    h.world.bump()
    h.run(SAMPLE)
    assert traction.bumper and traction.source == 'manual'
    _assert_cut_under_manual(h)


# -- the CONCIC-II: wheel speed commands straight to the world ------------------------------------
class ServoBox:
    """Writes steering_command every 10 ms (route following's rate): wheel speeds, motor on."""

    def __init__(self, world: WorldCore, left: int, right: int) -> None:
        self.world = world
        self.fields = {'mode': 'wheel_speeds', 'enable': 1, 'angle': 0, 'left_speed': left,
                       'right_speed': right}
        self.sending = True
        self.last = -1.0

    def run(self, seconds: float, until: Any = None) -> bool:
        w = self.world
        for _ in range(round(seconds / SAMPLE)):
            if self.sending and w.sample % 3 == 0:
                self.last = w.time
                w.on_record('steering_command', dict(self.fields), w.time)
            w.step()
            if until is not None and until():
                return True
        return False


def _concic2(model: str, left: int, right: int) -> tuple[WorldCore, ServoBox]:
    params = WorldParams(seed=3)
    params.concic2.model = model
    world = WorldCore(load_layout(layout_path('junction_1991')), params)
    box = ServoBox(world, left, right)
    box.run(2.5)
    assert world.pal.powered and world.vehicle.enable
    left_v, right_v = world.vehicle.wheel_speeds()
    assert abs(left_v - left / 1000.0) < 0.02 and abs(right_v - right / 1000.0) < 0.02
    return world, box


WHEELS = {'forward': (470, 470), 'reverse': (-300, -300), 'turning': (300, 500),
          'spin': (-200, 200)}


def _assert_concic2_rest(world: WorldCore, box: ServoBox, deceleration: float,
                         armature_open: bool) -> None:
    v = world.vehicle
    fastest = max(abs(s) for s in v.wheel_speeds())
    box.run(SAMPLE)
    assert not v.pushing
    if armature_open:  # the relays open the armatures: no current, friction only (6.3.11)
        assert v.i1 == 0.0 and v.i2 == 0.0
    box.run(fastest / deceleration + SAMPLE)
    assert v.wheel_speeds() == (0.0, 0.0), (v.wheel_speeds(), fastest / deceleration)
    at = (v.state.x, v.state.y, v.state.heading)
    box.run(1.0)  # the commands still ask for speed: the truck stays put
    assert (v.state.x, v.state.y, v.state.heading) == at


@pytest.mark.parametrize('wheels', list(WHEELS))
@pytest.mark.parametrize('model', ['dynamic', 'kinematic'])
def test_radio_stop_cuts_the_concic2_drive_in_the_world(model, wheels):
    world, box = _concic2(model, *WHEELS[wheels])
    world.set_radio_stop(True)
    dynamic = model == 'dynamic'
    # the dynamic model: friction only; the kinematic one coasts as after a motor-off command
    deceleration = concic2_friction_deceleration() if dynamic else CONCIC2['coast_deceleration']
    _assert_concic2_rest(world, box, deceleration, armature_open=dynamic)
    world.set_radio_stop(False)  # released: the same commands drive it again ...
    demands = [abs(s) / 1000.0 for s in WHEELS[wheels]]
    peaks = [0.0, 0.0]
    for _ in range(round(2.5 / SAMPLE)):  # the LM628 ramp: 0.3 m/s^2
        box.run(SAMPLE)
        speeds = world.vehicle.wheel_speeds()
        peaks = [max(peak, abs(s)) for peak, s in zip(peaks, speeds, strict=True)]
    # ... from rest, without a lurch: the servo loops restart from where the wheels stand
    # rather than catch up the travel they were asked for while cut (overshoot within the
    # 5 % of C.2.3.5)
    assert all(0.95 * d <= peak <= 1.05 * d for peak, d in zip(peaks, demands, strict=True)), peaks


@pytest.mark.parametrize('model', ['dynamic', 'kinematic'])
def test_bumper_cuts_the_concic2_drive_until_the_reset(model):
    world, box = _concic2(model, *WHEELS['forward'])
    world.bump()
    dynamic = model == 'dynamic'
    deceleration = concic2_friction_deceleration() if dynamic else CONCIC2['coast_deceleration']
    _assert_concic2_rest(world, box, deceleration, armature_open=dynamic)
    world.hardware_reset()  # the bumper frees; the PAL runs its start-up tests again
    box.run(1.0)
    assert world.pal.powered and world.vehicle.state.speed > 0.15


@pytest.mark.parametrize('wheels', list(WHEELS))
@pytest.mark.parametrize('model', ['dynamic', 'kinematic'])
def test_concic2_watchdog_cuts_the_motors_60_ms_after_the_last_command(model, wheels):
    """Commands stop: the PAL's watchdog cuts the amplifiers within 60 ms and one sample."""
    assert CONCIC2['watchdog'] == PAL_WATCHDOG  # the declared default is the thesis's
    world, box = _concic2(model, *WHEELS[wheels])
    v = world.vehicle
    box.sending = False
    box.run(1.0, until=lambda: not v.enable)
    off = world.time - box.last
    assert PAL_WATCHDOG < off <= PAL_WATCHDOG + SAMPLE + 1e-9, off
    assert (world.pal.state, world.pal.code, world.pal.watchdog) == ('fault', 7, True)
    assert not v.pushing
    fastest = max(abs(s) for s in v.wheel_speeds())
    # motor off: the kinematic wheels coast down; the dynamic model's speed loops brake them
    # to rest, at least as fast as friction alone would
    deceleration = (concic2_friction_deceleration() if model == 'dynamic'
                    else CONCIC2['coast_deceleration'])
    box.run(fastest / deceleration + 2 * SAMPLE)
    assert v.wheel_speeds() == (0.0, 0.0)
    box.sending = True  # the commands come back: the PAL stays latched until a reset
    box.run(0.5)
    assert world.pal.state == 'fault' and v.wheel_speeds() == (0.0, 0.0)


# -- the CONCIC-II under way on its own graph ---------------------------------------------------
@pytest.fixture(scope='module')
def under_way() -> Harness:
    """junction_1991 at cruise on a 'tape for 5.0 m' task (copied by each test)."""
    h = truck('junction_1991', seed=1)
    h.run(0.2)
    submit(h, 'tape for 5.0 m')
    assert h.run(4.0, until=lambda: h.world.vehicle.state.speed > 0.45)
    return h


def test_radio_stop_stops_the_concic2_and_its_software_names_it(under_way):
    """The world's cut stops the truck at once; route following then names the stop.

    The cut acts in the sample the stop is pressed, before any drive_status can tell route
    following of it (a record every 1 / drive_status_rate s): the hardware path is proven
    for itself. drive_status's radio_stop then makes the stop `radio_stop`, not a silent
    encoder (the wheels rightly stand still unpowered), and the executive fails the task
    naming it; released, the stop stays latched and named as it was.
    """
    h = copy.deepcopy(under_way)
    v, route, ex = h.world.vehicle, h.cores['route_following'], h.cores['executive']
    h.set_radio_stop(True)
    h.run(SAMPLE)
    assert not v.pushing and v.i1 == 0.0 and v.i2 == 0.0
    assert route.safety.fault == 'none'  # the software has heard nothing of it yet
    fastest = max(abs(s) for s in v.wheel_speeds())
    assert h.run(fastest / concic2_friction_deceleration() + SAMPLE,
                 until=lambda: v.wheel_speeds() == (0.0, 0.0))
    assert route.safety.fault == 'radio_stop' and not route.motor_on
    assert (ex.report['cause'], ex.report['detail']) == ('drive_fault', 'radio_stop'), ex.report
    h.run(2.0)  # well past the encoder check's time, still pressed
    assert route.safety.encoder == 'none'
    h.set_radio_stop(False)
    h.run(0.5)  # released: the stop stays latched until the next leg, the truck at rest
    assert route.safety.fault == 'radio_stop' and v.wheel_speeds() == (0.0, 0.0)


def test_the_watchdog_under_way_needs_no_software(under_way):
    """Route following's commands stop reaching the servos: the PAL alone turns the motors off.

    The world's amplifier cut is tested here, not route following's answer to drive_status:
    the first drive_status telling of the fault goes out at most 50 ms later, and the motors
    are off before it.
    """
    h = copy.deepcopy(under_way)
    heard: list[float] = []
    h.taps.append(lambda record, raw, now: heard.append(now)
                  if record == 'steering_command' else None)
    h.run(0.05)
    h.links['steering_command'] = Link(drop=1.0)
    last = heard[-1]
    v = h.world.vehicle
    assert h.run(1.0, until=lambda: not v.enable)
    assert PAL_WATCHDOG < h.now - last <= PAL_WATCHDOG + SAMPLE + 1e-9
    assert h.cores['route_following'].safety.fault == 'none'  # software has not heard yet

