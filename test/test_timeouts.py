"""Every safety timeout acts within one sample or period of its configured value.

Each value is read from the parameter file that declares it (a package's parameters.yaml, or
config/agv_demo.yaml where the graph sets its own), never copied here, so a timeout made 10 %
longer or shorter in the code fails a test: the act must come after the timeout and no later
than the next chance to see it (a loop pass, a world sample, a guide-wire sample). Where the
source fixes the value itself - the trip relay's 200 ms monostable (Baker 1983, App. B.2.1; the
traction_drive record table) and the CONCIC-II's 60 ms watchdog (Rajagopalan 1991, 6.3.11,
test_hardware_cuts.py) - the declared default is checked against it too. Records are sent half
a period off the checking clock, so no age ever equals a timeout exactly.
"""

from __future__ import annotations

from pathlib import Path
import re
from typing import Any

import pytest
from test_hardware_cuts import SAMPLE, DriveBox, declared
import yaml

from agv_nodes.communications.task_language import parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.navigation.core import NavigationCore
from agv_nodes.navigation.settings import NavigationParams
from agv_nodes.odometry import Odometer
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.junction_turn import JunctionTurn
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.traction.core import TractionCore
from agv_nodes.traction.settings import TractionParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import WorldParams

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[1]
TRACTION = declared('traction', 'TractionParams')
WORLD = declared('world', 'WorldParams')
ROUTE = declared('route_following', 'RouteParams')
WIRE = declared('route_following', 'WireParams')
TURNING = declared('route_following', 'TurningParams')
ENCODERS = declared('route_following', 'DriveSafetyParams')
NAVIGATION = declared('navigation', 'NavigationParams')
EXECUTIVE = declared('executive', 'ExecutiveParams')
EPS = 1e-9


def graph_parameters(node: str) -> dict[str, Any]:
    """Return what config/agv_demo.yaml (the graph's parameter file) sets for `node`."""
    text = (ROOT / 'config' / 'agv_demo.yaml').read_text(encoding='utf-8')
    return yaml.safe_load(text)[f'/**/{node}']['ros__parameters']


def record_table_monostable() -> float:
    """Return the trip relay's monostable as the traction_drive record table gives it, s."""
    text = (ROOT / 'msg_schemas' / 'traction_drive.yaml').read_text(encoding='utf-8')
    found = re.search(r'stops changing for (\d+) ms \(B\.2\.1\)', text)
    assert found, 'msg_schemas/traction_drive.yaml no longer states the monostable'
    return int(found.group(1)) / 1000.0


def record_period(record: str) -> float:
    """Return a record's period as its record table gives it, s."""
    text = (ROOT / 'msg_schemas' / f'{record}.yaml').read_text(encoding='utf-8')
    return yaml.safe_load(text)['period_ms'] / 1000.0


def within(elapsed: float, timeout: float, step: float) -> bool:
    """After the timeout, and no later than the next check one `step` on."""
    return timeout < elapsed <= timeout + step + EPS


# Where a parameter file sets a timeout as so many of its writer's heartbeats, the record
# table's period times that many: a default changed alone no longer says what its comment does.
HEARTBEATS = [
    ('traction', 'TractionParams', 'command_timeout', ['traction_command'], 3),
    ('executive', 'ExecutiveParams', 'status_timeout',
     ['navigation_status', 'traction_status', 'route_status', 'load_status', 'comms_status'], 3),
    ('navigation', 'NavigationParams', 'sensor_timeout', ['position_sensor_status'], 5)]


@pytest.mark.parametrize('package, section, name, records, beats', HEARTBEATS,
                         ids=[h[2] for h in HEARTBEATS])
def test_a_timeout_is_the_heartbeats_its_parameter_file_says(package, section, name, records,
                                                             beats):
    for record in records:
        assert declared(package, section)[name] == pytest.approx(beats * record_period(record))


# -- traction ------------------------------------------------------------------------------------
def command(demand: int, priority: int = 1) -> dict[str, int]:
    return {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': demand,
            'executive_priority': priority}


class Loop:
    """A TractionCore on its loop period; the executive's command every 50 ms between passes.

    `link` (navigation's, every 20 ms) and `odometry` (the world's, 100 Hz) when set.
    """

    def __init__(self, **params: Any) -> None:
        self.core = TractionCore(TractionParams(**params))
        self.period = self.core.p.loop_period
        self.k = 0
        self.command: dict | None = command(0)
        self.link: dict | None = None
        self.odometry = False
        self.last = {'traction_command': -1.0, 'traction_link': -1.0}

    @property
    def now(self) -> float:
        return self.k * self.period

    def run(self, seconds: float, until: Any = None) -> bool:
        for _ in range(round(seconds / self.period)):
            half = self.now + self.period / 2  # records arrive between passes
            ms = round(self.now * 1000)
            if self.command is not None and ms % 50 == 0:
                self.core.on_record('traction_command', self.command, half)
                self.last['traction_command'] = half
            if self.link is not None and ms % 20 == 0:
                self.core.on_record('traction_link', self.link, half)
                self.last['traction_link'] = half
            if self.odometry:
                self.core.on_record('wheel_odometry', {
                    'left_speed': 0, 'right_speed': 0, 'left_distance': 0,
                    'right_distance': 0, 'sample': 0}, half)
            self.k += 1
            self.core.tick(self.now)
            if until is not None and until():
                return True
        return False

    def arm(self) -> None:
        self.run(0.2)
        self.command = command(30)
        self.run(1.0)
        assert not self.core.tripped

    def trip_after(self, record: str, cause: str) -> float:
        """Silence `record`; return how long after its last arrival the relay opened."""
        if record == 'traction_command':
            self.command = None
        else:
            self.link = None
        assert self.run(2.0, until=lambda: self.core.tripped)
        assert self.core.trip_cause == cause and self.core.drive()['contactor'] == 0
        return self.now - self.last[record]


def test_declared_defaults_are_set_where_the_graph_does_not_override_them():
    """The values these tests read are the ones TractionParams and WorldParams take."""
    p = TractionParams()
    assert (p.command_timeout, p.link_timeout, p.stall_limit, p.stale_confirm) == (
        TRACTION['command_timeout'], TRACTION['link_timeout'], TRACTION['stall_limit'],
        TRACTION['stale_confirm'])
    w = WorldParams()
    assert (w.drive_watchdog, w.steering_timeout) == (WORLD['drive_watchdog'],
                                                      WORLD['steering_timeout'])


def test_stale_command_trips_one_pass_after_command_timeout():
    b = Loop()
    b.arm()
    assert within(b.trip_after('traction_command', 'stale_command'),
                  TRACTION['command_timeout'], b.period)


def test_stale_link_trips_one_pass_after_link_timeout():
    b = Loop()
    b.arm()
    b.command = command(60, priority=0)
    b.link = {'executive_priority': 0, 'reverse': 0, 'speed': 20}
    b.run(1.0)
    assert b.core.source == 'position'
    assert within(b.trip_after('traction_link', 'stale_link'), TRACTION['link_timeout'],
                  b.period)


@pytest.mark.parametrize('odometry', [True, False], ids=['odometry', 'odometry_silent'])
def test_the_graphs_stale_command_timeout_and_its_backstop(odometry):
    """config/agv_demo.yaml: command_timeout with stale_confirm odometry records since.

    With the odometry arriving the count is met before the timeout, so the timeout trips; with
    none arriving (a starved process's clock alone) the age trips at twice the timeout.
    """
    graph = graph_parameters('traction')
    b = Loop(command_timeout=graph['command_timeout'], stale_confirm=graph['stale_confirm'])
    b.odometry = odometry
    assert graph['stale_confirm'] * 0.01 < graph['command_timeout']  # 100 Hz odometry
    b.arm()
    timeout = graph['command_timeout'] * (1 if odometry else 2)
    assert within(b.trip_after('traction_command', 'stale_command'), timeout, b.period)


@pytest.mark.parametrize('beyond', [-1, 1], ids=['within', 'beyond'])
def test_a_stalled_loop_trips_beyond_stall_limit(beyond):
    b = Loop()
    b.arm()
    gap = TRACTION['stall_limit'] + beyond * 0.001  # a millisecond either side
    at = b.now + gap
    b.core.on_record('traction_command', b.command, at)  # fresh: only the gap can trip
    b.core.tick(at)
    if beyond > 0:
        assert b.core.tripped and b.core.trip_cause == 'stalled_loop'
    else:
        assert not b.core.tripped


# -- the world: the trip relay's monostable and the tug's steering watchdog ---------------------
def test_the_trip_relay_opens_200_ms_after_the_watchdog_count_stops():
    """Baker 1983, App. B.2.1: the relay releases when MONO stops retriggering it for 200 ms."""
    assert WORLD['drive_watchdog'] == record_table_monostable()
    world = WorldCore(load_layout(layout_path('straight_track')), WorldParams(seed=3))
    box = DriveBox(world, 40, True)
    box.run(3.0)
    v = world.vehicle
    assert v.relay_closed and v.pushing
    changed = box.sent  # the traction loop stalls: its last record keeps coming, every 10 ms
    for k in range(round(1.0 / SAMPLE)):
        if k % 3 == 2:
            world.on_record('traction_drive', {**box.fields, 'watchdog': box.count}, world.time)
        world.step()
        if not v.relay_closed:
            break
    assert not v.relay_closed and not v.pushing
    assert within(world.time - changed, WORLD['drive_watchdog'], SAMPLE)


def test_the_tug_holds_its_steering_angle_after_steering_timeout():
    world = WorldCore(load_layout(layout_path('straight_track')), WorldParams(seed=3))
    v = world.vehicle
    last = 0.0
    for k in range(340):
        if k % 3 == 0:
            last = world.time
            world.on_record('steering_command', {'mode': 'angle', 'enable': 1, 'angle': 100,
                                                 'left_speed': 0, 'right_speed': 0}, last)
        world.step()
    assert v.steer_enable
    while v.steer_enable and world.time < 2.0:
        world.step()
    assert within(world.time - last, WORLD['steering_timeout'], SAMPLE)


# -- navigation ----------------------------------------------------------------------------------
def test_navigation_is_lost_one_pass_after_sensor_timeout():
    core = NavigationCore(NavigationParams())
    period = core.p.period
    sensor = {'recognised': 0, 'invalid': 0, 'adc_stale': 0, 'table': 'navigating',
              'saturated': 0, 'code': 0, 'identity': 0xFF, 'stop_view': 0, 'recognitions': 0,
              'sample_count': 0, 'epoch': 0}

    def take(out: dict | None) -> None:  # the table the sensor is told to use
        command = (out or {}).get('position_sensor_command')
        if command:
            sensor.update(table=command['table'], epoch=command['epoch'])

    take(core.on_record('navigation_command', {'task_location': 2, 'stop_marker': 0}, 0.0))
    last, k = 0.0, 0
    for k in range(1, 101):  # 1 s of the sensor's 20 ms heartbeats, between passes
        if k % 2 == 0:
            last = k * period - period / 2
            take(core.on_record('position_sensor_status', dict(sensor), last))
        take(core.tick(k * period))
    assert not core.sensor_lost and core.mode == 'navigating'
    while not core.sensor_lost and k < 200:  # the sensor falls silent
        k += 1
        take(core.tick(k * period))
    assert core.sensor_lost
    assert within(k * period - last, NAVIGATION['sensor_timeout'], period)


# -- route following -----------------------------------------------------------------------------
def test_an_srm_that_finds_no_wire_ends_lost_at_srm_timeout():
    """The search ends LOST on the first guide-wire sample after srm_timeout (100 Hz)."""
    route = RouteCore(RouteParams())
    step = 1.0 / WORLD['guide_wire_rate']
    nominal = round(route.p.wire.nominal)
    t, sent = 0.0, []

    def feed(seconds: float, coil: int, until: Any = None) -> bool:
        nonlocal t
        for _ in range(round(seconds / step)):
            t = round(t + step, 6)
            route.on_record('wheel_odometry', {'left_speed': 300, 'right_speed': 300,
                                               'left_distance': 0, 'right_distance': 0}, t)
            route.on_record('guide_wire', {'left_coil': coil, 'right_coil': coil}, t)
            out = route.tick(t)
            sent.append(out.get('route_status', {}).get('state'))
            if until is not None and until():
                return True
        return False

    route.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                      'junction': 'straight', 'manoeuvre': 0}, 0.0)
    feed(1.0, nominal)
    assert route.state == 'following'
    began = t + step / 2  # the command comes between two samples
    route.on_record('route_command', {'mode': 'srm', 'srm_angle': 20, 'junction': 'straight',
                                      'manoeuvre': 1}, began)
    assert route.state == 'srm_running'
    assert feed(2 * WIRE['srm_timeout'], 0, until=lambda: route.state == 'lost')
    assert within(t - began, WIRE['srm_timeout'], step)
    assert 'lost' in sent


class StraightLaw:
    """The camera law's wheel speeds for a straight approach (no frames needed)."""

    def wheel_speeds(self, speed: float, steer: float) -> tuple[float, float]:
        return speed, speed


@pytest.mark.parametrize('wait', [0.0, 2.5])
def test_a_junction_turn_whose_wheels_never_count_times_out(wait):
    """turn_timeout (plus a scripted wait) from the sighting: motors off, LOST."""
    params = RouteParams(vehicle='concic2')
    turn, odo, law = JunctionTurn(params), Odometer(), StraightLaw()
    turn.begin('left', 'left', wait, 1, odo)
    period = ROUTE['period']
    began = 0.5 * period
    k, result = 0, ''
    while result == '' and k < 10000:
        now = began + k * period
        result = turn.step(now, odo, (0.0, 0.0), 0.0, 0.0, law)
        k += 1
    assert result == 'timeout' and turn.wheels == (0.0, 0.0)
    assert within(now - began, TURNING['turn_timeout'] + wait, period)


# -- the executive -------------------------------------------------------------------------------
TASK = parse_task('stop at 2 first').record() | {'task_id': 1}
HEALTHY = {
    'navigation': {'at_location': 0, 'slow': 0, 'reverse': 0, 'lost': 0, 'last_marker': 0xFF,
                   'speed_request': 0x40, 'sensor_lost': 0, 'input_fault': 0, 'stop_view': 0},
    'traction': {'ref': 55, 'duty': 55, 'emergency_stop': 0, 'radio_stop': 0, 'bumper': 0,
                 'tripped': 0, 'manual': 0, 'field_forward': 1, 'armature_on': 1,
                 'reversing': 0, 'source': 'executive', 'trip_cause': 'none', 'speed': 700},
    'route': {'state': 'following', 'lateral_error': 0, 'signal': 100, 'steering': 0,
              'sign_left': 0, 'sign_right': 0, 'sign_straight': 0, 'manoeuvre': 0},
    'load': {'state': 'idle', 'cause': 'none', 'load_first': 0, 'load_second': 0, 'job': 0},
    'comms': TASK}


class Supervised:
    """An executive on its clocks: a pass every period, supervision every supervision_period.

    The sub-systems' statuses arrive between checks, each every `every` s, but `silent` ones.
    """

    def __init__(self, params: ExecutiveParams) -> None:
        self.ex = ExecutiveCore(params)
        self.check = params.supervision_period
        self.passes = round(params.period / self.check)
        self.k = 0
        self.silent: set[str] = set()
        self.every = 0.05
        self.heard: dict[str, float] = {}
        self.traction = dict(HEALTHY['traction'])

    def run(self, seconds: float, until: Any = None) -> bool:
        for _ in range(round(seconds / self.check)):
            half = (self.k + 0.5) * self.check
            if round(half * 1000 - 5) % round(self.every * 1000) == 0:
                for sub, fields in HEALTHY.items():
                    if sub not in self.silent:
                        fields = self.traction if sub == 'traction' else fields
                        self.ex.on_record(f'{sub}_status', dict(fields), half)
                        self.heard[sub] = half
            self.k += 1
            now = self.k * self.check
            if self.k % self.passes == 0:
                self.ex.tick(now)
            else:
                self.ex.supervise(now)
            if until is not None and until():
                return True
        return False

    @property
    def now(self) -> float:
        return self.k * self.check


def _graph_or_declared(source: str) -> ExecutiveParams:
    if source == 'declared':
        return ExecutiveParams()
    graph = graph_parameters('executive')
    return ExecutiveParams(status_timeout=graph['status_timeout'],
                           stale_confirm=graph['stale_confirm'])


@pytest.mark.parametrize('source', ['declared', 'graph'])
def test_a_silent_subsystem_fails_the_task_one_check_after_status_timeout(source):
    params = _graph_or_declared(source)
    timeout = (EXECUTIVE['status_timeout'] if source == 'declared'
               else graph_parameters('executive')['status_timeout'])
    s = Supervised(params)
    s.every = 0.01  # the others' records keep coming: the count never delays it
    s.run(1.0)
    assert s.ex.mode == 'running'
    s.silent = {'traction'}
    assert s.run(1.0, until=lambda: s.ex.mode == 'failed')
    assert s.ex.fault == ('stale_status', 'traction')
    assert within(s.now - s.heard['traction'], timeout, s.check)


def test_with_everyone_silent_the_age_alone_fails_the_task_at_twice_status_timeout():
    """No records arrive to confirm it (a starved executive's clock): 2 x status_timeout."""
    s = Supervised(ExecutiveParams())
    s.run(1.0)
    last = max(s.heard.values())
    s.silent = set(HEALTHY)
    assert s.run(1.0, until=lambda: s.ex.mode == 'failed')
    assert s.ex.fault[0] == 'stale_status'
    assert within(s.now - last, 2 * EXECUTIVE['status_timeout'], s.check)


def test_a_traction_trip_fails_the_task_only_after_trip_grace():
    """Tripped since before the task: armed again and again, failed once trip_grace is over."""
    s = Supervised(ExecutiveParams())
    s.traction = {**HEALTHY['traction'], 'tripped': 1, 'trip_cause': 'startup',
                  'source': 'trip'}
    s.run(s.check)
    began = s.heard['comms']  # the task came with communications' first status
    assert s.ex.mode == 'running' and s.ex.task_id == TASK['task_id']
    assert s.run(3.0, until=lambda: s.ex.mode == 'failed')
    assert s.ex.fault == ('tripped', 'traction')
    assert within(s.now - began, EXECUTIVE['trip_grace'], s.check)
