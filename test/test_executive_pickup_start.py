"""A task that meets the world's start: the route has not yet heard its guide-wire pickup.

On sim time the graph's clock stands at 0 until the world moves, so a task taken just before
starts at 0; the executive's first pass (~60 ms) puts route following into follow_wire, and
without a pickup sample for lost_samples * 10 ms + 50 ms the route used to say LOST while the
truck stood on its wire, failing the task `lost wire (route)`. Here executive and route
following run back to back on the timers a launched graph gives them, the other sub-systems
report as healthy ones do, and the pickup stream starts late, never, or is lost while driving.
"""

from __future__ import annotations

import pytest
from test_executive_comms_load import status_records

from agv_nodes.communications.task_language import parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.diagnostics import ERROR, WARN, HealthMonitor
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.harness import truck
from agv_nodes.route_following.core import RouteCore

CLOCK_START = 9  # ms: the world's first /clock (3 samples at 340 Hz); timers run from there
NOMINAL = 732  # a coil's reading with the wire midway (RouteParams.wire.nominal)


class StartUp:
    """Executive and route following wired together on a 1 ms grid of sim time."""

    def __init__(self) -> None:
        self.ex, self.route = ExecutiveCore(ExecutiveParams()), RouteCore()
        self.demand = 0  # the last traction demand the executive sent
        self.sent: list[tuple[float, int, str]] = []  # (t, demand, route state it had)
        self.fault_at: float | None = None
        # the task is taken at 0, before the world moves (its clock still stands at 0)
        self.ex.on_record('comms_status',
                          parse_task('stop at 2 first').record() | {'task_id': 1}, 0.0)

    def _to_route(self, commands: dict | None, t: float) -> None:
        if commands:
            self.demand = commands['traction_command']['demand']
            route_state = (self.ex.status.get('route') or {}).get('state', '')
            self.sent.append((t, self.demand, route_state))
            self._to_executive(self.route.on_record('route_command', commands['route_command'],
                                                    t), t)

    def _to_executive(self, outputs: dict | None, t: float) -> None:
        if outputs and 'route_status' in outputs:
            self._to_route(self.ex.on_record('route_status', outputs['route_status'], t), t)

    def run(self, until: float, wire_from: float | None, weak_from: float | None = None) -> None:
        """Step to `until` s; pickup samples from wire_from (None: never), weak from weak_from."""
        speed = 0
        for ms in range(CLOCK_START, round(until * 1000) + 1):
            t = ms / 1000.0
            if ms % 10 == 2:  # 100 Hz: wheel odometry, and the pickup once it speaks
                speed = 600 if self.demand > 0 else 0  # a truck driven moves, in this model
                self.route.on_record('wheel_odometry', {
                    'left_speed': speed, 'right_speed': speed, 'left_distance': 0,
                    'right_distance': 0}, t)
                if wire_from is not None and t >= wire_from:
                    coil = 50 if weak_from is not None and t >= weak_from else NOMINAL
                    self.route.on_record('guide_wire', {'left_coil': coil, 'right_coil': coil}, t)
            if ms >= CLOCK_START + 10 and ms % 10 == 9:  # route's 10 ms loop
                self._to_executive(self.route.tick(t), t)
            if ms >= CLOCK_START + 50 and ms % 50 == 9:  # the others' statuses, then the pass
                for name, fields in status_records(t).items():
                    fields = {**fields, 'speed': speed} if name == 'traction' else fields
                    if name != 'route':  # route following's own come from its core
                        self._to_route(self.ex.on_record(f'{name}_status', fields, t), t)
                self._to_route(self.ex.tick(t), t)
            elif ms >= CLOCK_START + 10 and ms % 10 == 9:  # the supervision timer
                self._to_route(self.ex.supervise(t), t)
            if self.fault_at is None and self.ex.fault is not None:
                self.fault_at = t

    def driven_while(self, states: tuple[str, ...]) -> list[tuple[float, int, str]]:
        """Return the demands sent while the executive's route status was one of `states`."""
        return [s for s in self.sent if s[1] != 0 and s[2] in states]


@pytest.mark.timeout(60)
def test_a_pickup_heard_late_at_the_start_holds_the_task_then_drives():
    # The first sample 0.25 s after the world moved: after the route's 110 ms quiet limit.
    run = StartUp()
    run.run(0.6, wire_from=0.25)
    assert run.ex.fault is None and run.ex.mode == 'running', run.ex.notes.texts()
    assert 'unheard' in [s[2] for s in run.sent]  # the route said so, and was held on
    assert not run.driven_while(('lost', 'unheard'))
    first = next(t for t, demand, _state in run.sent if demand)
    assert 0.25 < first < 0.25 + 0.06  # driven at the executive's first pass once heard
    assert run.sent[-1][1] == ExecutiveParams().cruise_demand


@pytest.mark.timeout(60)
def test_a_pickup_that_never_speaks_fails_the_task_within_trip_grace():
    run = StartUp()
    run.run(2.0, wire_from=None)
    assert run.ex.fault == ('lost_wire', 'route')
    grace = ExecutiveParams().trip_grace
    assert grace < run.fault_at <= grace + 0.011  # the supervision timer's 10 ms after it
    assert any('pickup not heard' in text for text in run.ex.notes.texts())
    assert not [s for s in run.sent if s[1] != 0]  # never driven
    assert run.route.steering_command()['angle'] == 0


@pytest.mark.timeout(60)
def test_a_wire_lost_while_driving_still_fails_at_once():
    run = StartUp()
    run.run(0.5, wire_from=0.02)
    assert run.ex.fault is None and run.demand == ExecutiveParams().cruise_demand
    run.run(1.0, wire_from=0.02, weak_from=0.5)  # the wire goes under the moving truck
    assert run.ex.fault == ('lost_wire', 'route')
    # lost_samples weak samples, then the status on the route's next 10 ms pass
    assert run.fault_at <= 0.5 + 0.05 + 0.02
    assert not run.driven_while(('lost', 'unheard'))


@pytest.mark.timeout(60)
def test_a_route_that_has_not_heard_its_pickup_says_unheard_and_does_not_steer():
    route = RouteCore()
    out = route.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                            'junction': 'straight', 'manoeuvre': 0}, 0.0)
    assert out['route_status']['state'] == 'unheard'
    for k in range(1, 100):  # a second of silence: still unheard, not lost
        route.tick(k * 0.01)
    assert route.state == 'unheard' and route.status()['state'] == 'unheard'
    assert route.steering_command()['angle'] == 0
    route.on_record('guide_wire', {'left_coil': NOMINAL, 'right_coil': NOMINAL}, 1.0)
    assert route.state == 'following'
    for k in range(101, 130):  # heard, then silent: LOST as before
        route.tick(k * 0.01)
    assert route.state == 'lost'


@pytest.mark.timeout(120)
def test_diagnostics_warn_of_a_pickup_not_yet_heard_and_err_on_a_lost_wire():
    h = truck('demo_1983', seed=1)
    ex = h.cores['executive']
    member = next(m for m in h.members if m.core is ex)
    monitor = HealthMonitor()
    h.run(1.0)
    route = member.readers['route_status']
    for state, level, message in (('unheard', WARN, 'guide-wire pickup not yet heard'),
                                  ('lost', ERROR, 'guide wire lost')):
        route.fields = dict(route.fields, state=state)
        rows = {r.name: r for r in monitor.update(h.now, member.readers, member.writers, ex)}
        assert (rows['route'].level, rows['route'].message) == (level, message)
