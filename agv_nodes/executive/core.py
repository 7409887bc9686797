"""The Vehicle Executive: tasks into commands for every sub-system, and the truck's health.

It talks to the sub-systems only through their command and status records (thesis 3.5.3). A task
becomes an itinerary (fig 3.1, level 2) of steps, each run through the records (level 3):

    goto(n, edge)   navigation_command {n, edge}; cruise until navigation reports 0BH at n
    next_marker(n)  navigation_command {n, 1} (byte 2 alone changes): position to the next marker
    load / unload   load_command job, wait for load_status done or failed
    wait(s)         dwell
    srm(n, angle)   cruise, reporting landmarks, until n is passed, then leave the wire there
    continue        cruise on along the wire (the task is over, the truck keeps going)

At each location marker reported the route map decides continue or SRM (the demo floor needs one at
L1 and L3 every lap); wire changes run at `srm_demand`, slow until the next landmark (thesis 7.2).
An `at` task (agv_nodes.executive.set_down; modern) runs no itinerary: it tells a truck set down
by hand at which stop marker it stands, so that it leaves there as from a stop of its own.
Traction's byte 2 stays non-zero while navigation positions the truck. A pause (modern:
agv_nodes.executive.pause) holds the truck at rest, its task kept, until resumed. Faults - wire
or marker sensor lost, a stale status, over `reject_limit` rejected records in a second, a
sub-system fault (traction tripped, radio stop, load failed) or restart (its status from a new
writer: whatever it knew of the task is gone), a step longer than `route_limit` - give an emergency
stop (traction byte 2 = 00H) and fail the task naming cause and sub-system until a new task.

A status is stale when older than `status_timeout` *and* `stale_confirm` records from the others
have arrived since (or twice that old): after a stall a starved executive's /clock jumps ahead at
once while its queued records are taken one per topic per turn; the count keeps it from blaming a
record still queued. `status_age: sent` ages a status from its send (agv_nodes.sent_time).
"""

from typing import Any

from agv_nodes.executive.faults import SUBSYSTEM_OF, SUBSYSTEMS, FaultSupervision
from agv_nodes.executive.itinerary import NO_TASK, Step, itinerary
from agv_nodes.executive.pause import Pause
from agv_nodes.executive.set_down import SetDown
from agv_nodes.executive.settings import ExecutiveParams, parse_srm_map
from agv_nodes.executive.tape_legs import NO_BRANCH_FIELDS, TapeLegs
from agv_nodes.records.ports import DUPLICATE_WRITER
from agv_nodes.subsystem import SubsystemCore

EXPLORE = 31  # a location identity no marker carries: "cruise and report every landmark"
TAPE_STEPS = ('tape', 'tape_reverse', 'reckon')
CAMERA_OPS = ('tape', 'reckon', 'manual', 'calibrate')  # the camera truck's tasks


class ExecutiveCore(FaultSupervision, SetDown, Pause, SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'executive', ExecutiveParams, 'period'

    def __init__(self, params: ExecutiveParams | None = None) -> None:
        super().__init__(params)
        self.srm_map = parse_srm_map(self.p.srm_map)  # location -> SRM angle, degrees
        self._last_tick: float | None = None
        self.supervision_period = self.p.supervision_period
        self.status: dict[str, dict[str, Any]] = {}  # latest status record per sub-system
        self.status_time: dict[str, float] = {}
        self.max_age: dict[str, float] = {}  # oldest status seen while supervising (diagnostics)
        self.arrivals = 0  # status records received, all sub-systems
        self.arrivals_at: dict[str, int] = {}  # the count when each sub-system last reported
        self.rejects: list[tuple[float, str]] = []  # (time, writer) of rejected records
        self.mode = 'idle'  # idle | running | cruising | failed
        self.task: dict[str, Any] | None = None
        self.task_id = 0
        self.steps: list[Step] = []
        self.index = 0
        self.phase = ''
        self.phase_time = 0.0
        self.report = {'state': 'idle', 'cause': 'none', 'subsystem': 'none'}
        self.fault: tuple[str, str] | None = None
        self.demand = 0
        self.nav = (NO_TASK, 0)
        self.camera = self.p.guidance == 'camera'
        self.subsystems = SUBSYSTEMS[self.p.guidance]
        self.route = {'mode': 'idle' if self.camera else 'follow_wire', 'srm_angle': 0,
                      'junction': 'straight', 'manoeuvre': 0}
        self.tape = TapeLegs(self.p.junction_seed, self.p.leg_rest_time)
        self.load = {'action': 'idle', 'conveyor': 'first', 'timeout': self.p.load_timeout,
                     'job': 0}
        self.slow = False  # after an SRM, until the next landmark
        self.last_marker = NO_TASK
        self._srm_pending: int | None = None  # SRM angle to start at the next landmark n
        self._srm_at: int | None = None
        self._srm_manoeuvre = 0
        self.stopped_at: int | None = None  # the location the truck last stopped at
        self.stop_marker: int | None = None  # and its stop marker there (0 first, 1 second)
        self.distance = 0.0  # m travelled in the current step (from traction's speed)
        self.distance_since_landmark = 0.0
        self.positioning_distance = 0.0
        self.task_start = 0.0
        self.arm_until = 0.0

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float,
                  sent: float | None = None) -> dict | None:
        """Take a status record or a task, aged from `sent` (agv_nodes.sent_time) or else `now`."""
        sub = SUBSYSTEM_OF.get(record)
        if sub is not None:
            self.status[sub] = fields
            self.status_time[sub] = now if sent is None else min(sent, now)
            self.arrivals += 1
            self.arrivals_at[sub] = self.arrivals
            if sub == 'communications':
                self._pause_record(fields, now)
                self._task_record(fields, now)
            elif sub == 'navigation':
                self._navigation(fields, now)
        if self.mode in ('running', 'cruising'):
            # Not only at the tick: a silent sub-system is noticed within ~10 ms of its timeout
            # and the e-stop goes out at once (fault budget: drive off within 200 ms).
            self._supervise(now)
            if self.mode == 'failed':
                return self._commands(now)
        return None

    def sent_later(self, record: str, sent: float) -> None:
        """Age a status from `sent`, learnt after it was taken (the clock queue was behind)."""
        sub = SUBSYSTEM_OF.get(record)
        if sub in self.status_time:
            self.status_time[sub] = max(self.status_time[sub], sent)

    def on_reject(self, record: str, reason: str, now: float) -> dict | None:
        """Count rejected status records (a burst of them is a fault; a duplicate writer is)."""
        if reason == DUPLICATE_WRITER:
            return self.on_duplicate_writer(record, now)
        self.rejects.append((now, SUBSYSTEM_OF.get(record, 'none')))
        return None

    def on_writer_restart(self, record: str, now: float) -> dict | None:
        """Fail the task: a sub-system that restarts during one has lost what it knew of it."""
        if self.mode not in ('running', 'cruising') or record not in SUBSYSTEM_OF:
            return None
        self._fail(now, 'restarted', SUBSYSTEM_OF[record], f'{record} from a new writer')
        return self._commands(now)

    def _task_record(self, fields: dict[str, Any], now: float) -> None:
        if fields['task_id'] == 0 or fields['task_id'] == self.task_id:
            return
        self.task_id = fields['task_id']
        self.task = fields
        if fields['op'] == 'abort':
            self._stop_everything()
            self.mode = 'idle'
            self.report = {'state': 'completed', 'cause': 'none', 'subsystem': 'none'}
            self._log(now, f'task {self.task_id}: abort')
            return
        foreign = (fields['op'] in CAMERA_OPS) != self.camera
        if fields['op'] == 'at' and not foreign:  # where the truck stands (modern: set_down)
            return self._set_down(fields, now)
        steps = itinerary(fields)
        if not steps or foreign:
            self.report = {'state': 'rejected', 'cause': 'bad_task', 'subsystem': 'none'}
            why = 'no itinerary' if not foreign else \
                f'a {fields["op"]} task, on a truck with {self.p.guidance} guidance'
            self._log(now, f'task {self.task_id}: rejected ({why})')
            return
        self.steps, self.index, self.mode, self.fault = steps, 0, 'running', None
        self.task_start = now
        traction = self.status.get('traction')
        if not self.camera and (traction is None or traction.get('tripped')):
            # 00H first: traction's trip latch clears on 00H then non-zero. Only a tripped
            # traction needs it: sent to a truck cruising on from the last task it is an
            # emergency stop pulse (the closed loop brakes to rest on it).
            self.arm_until = now + 2 * self.p.period
        self.report = {'state': 'accepted', 'cause': 'none', 'subsystem': 'none'}
        self._log(now, f'task {self.task_id}: {len(steps)} steps: '
                  + '; '.join(s.name for s in steps))
        self._enter(now)

    def _navigation(self, fields: dict[str, Any], now: float) -> None:
        """Landmarks: every change of the last marker while navigating is a decision point."""
        marker = fields['last_marker']
        if fields['at_location']:  # OUTFO[1] = the task location: not a landmark report
            self.last_marker = marker if marker <= 31 else self.last_marker
            self.slow = False  # a location reached after an SRM: the slow stretch is over
            return
        if marker == self.last_marker or marker > 31:
            return
        self.last_marker = marker
        self.distance_since_landmark = 0.0
        self._log(now, f'landmark L{marker}')
        if self.step is not None and self.step.kind == 'pass' and marker == self.step.location:
            self.phase = 'passed'
        if self.slow and self.route['mode'] == 'follow_wire':
            self.slow = False  # the landmark after an SRM: back to cruise
        angle = self._srm_pending if (self._srm_at == marker) else self.srm_map.get(marker)
        if angle is not None and self.mode in ('running', 'cruising'):
            self._start_srm(marker, angle, now)

    def _start_srm(self, marker: int, angle: int, now: float) -> None:
        self._srm_manoeuvre = (self._srm_manoeuvre + 1) & 0xFF or 1
        self.route = {'mode': 'srm', 'srm_angle': angle, 'junction': 'straight',
                      'manoeuvre': self._srm_manoeuvre}
        self.slow = True
        self._log(now, f'SRM at L{marker}: {angle:+d} deg (manoeuvre {self._srm_manoeuvre})')
        if self._srm_at == marker:
            self._srm_at, self._srm_pending = None, None

    # -- itinerary --------------------------------------------------------------------------
    @property
    def step(self) -> Step | None:
        """The step being run."""
        running = self.mode == 'running' and self.index < len(self.steps)
        return self.steps[self.index] if running else None

    def _enter(self, now: float) -> None:
        step = self.step
        self.phase, self.phase_time, self.distance = 'start', now, 0.0
        if step is None:
            return
        self._log(now, f'step {self.index + 1}/{len(self.steps)}: {step.name}')
        self.report = {'state': 'running', 'cause': 'none', 'subsystem': 'none'}
        if step.kind in ('goto', 'srm', 'continue', 'pass'):
            self.demand = self.p.cruise_demand
            departing, self.stopped_at, self.stop_marker = self.stopped_at, None, None
            if departing is not None and (departing in self.srm_map or (
                    step.kind == 'srm' and step.location == departing)):
                # Stopped at an SRM location's workstation: the manoeuvre starts on departure.
                angle = step.value if step.kind == 'srm' and step.location == departing \
                    else self.srm_map[departing]
                self._start_srm(departing, angle, now)
                if step.kind == 'srm' and step.location == departing:
                    step = Step('continue', name=step.name)
                    self.steps[self.index] = Step('srm_landing', departing, value=angle,
                                                  name=self.steps[self.index].name)
            if step.kind == 'goto':
                self.nav = (NO_TASK, 0)  # withdraw first, so an identical task is new
                self.phase = 'release'
            elif step.kind == 'srm':
                self.nav = (EXPLORE, 0)
                self._srm_at, self._srm_pending = step.location, step.value
                self.phase = 'wait_landmark'
            elif step.kind == 'pass':  # cruise, every landmark reported, until it is passed
                self.nav = (EXPLORE, 0)
                self.phase = 'wait_landmark'
            else:
                self.nav = (EXPLORE, 0)
        elif step.kind == 'next_marker':
            self.nav = (step.location, 1)
            self.demand = self.p.cruise_demand
            self.phase = 'wait_positioning'
        elif step.kind in ('load', 'unload'):
            self.load = {'action': step.kind, 'conveyor': 'second' if step.value else 'first',
                         'timeout': self.p.load_timeout, 'job': (self.load['job'] + 1) & 0xFF}
            self.phase = 'transfer'
        elif step.kind == 'wait':
            self.phase = 'dwell'
        elif step.kind in TAPE_STEPS:
            self.route = self.tape.start(self.task or {}, step.kind, step.value, self.route)
            self.phase = 'leg'
        elif step.kind in ('manual', 'calibrate'):  # App. F.4, F.3: route following's modes
            self.route = {**self.route, 'mode': 'manual' if step.kind == 'manual' else
                          'calibration', 'direction': 'reverse' if step.value and
                          step.kind == 'calibrate' else 'forward'}

    def _advance(self, now: float) -> None:
        step = self.step
        if step is not None and step.kind in ('goto', 'next_marker'):
            self.stopped_at, self.stop_marker = step.location, step.edge
        self.index += 1
        if self.index >= len(self.steps):
            last = self.steps[-1].kind
            self.mode = 'cruising' if last == 'continue' else 'idle'
            if self.mode == 'idle':
                self.demand = 0  # stay put until the next order (e-stop hold)
                if self.camera:
                    self.route = {**self.route, 'mode': 'idle'}
            self.report = {'state': 'completed', 'cause': 'none', 'subsystem': 'none'}
            self._log(now, f'task {self.task_id}: completed')
            return
        self.report = {'state': 'step_done', 'cause': 'none', 'subsystem': 'none'}
        self._enter(now)

    def _settle(self, now: float) -> None:
        """0BH came while the truck still coasts: the stop is done once it is at rest."""
        speed = abs((self.status.get('traction') or {}).get('speed', 0))
        if speed > self.p.rest_speed:
            self.phase_time = now
        elif now - self.phase_time >= self.p.rest_time:
            self._advance(now)

    def _run_step(self, now: float) -> None:
        step = self.step
        nav = self.status.get('navigation') or {}
        if step is None:
            return
        arrived = nav.get('at_location') == 1 and nav.get('lost') == 1 and \
            nav.get('last_marker') == step.location
        if step.kind in ('goto', 'next_marker') and self.phase in ('positioning', 'settling'):
            if self.phase == 'settling':
                self._settle(now)
            elif arrived:
                self.phase, self.phase_time = 'settling', now
        elif step.kind == 'goto':
            if self.phase == 'release':
                if now - self.phase_time >= 2 * self.p.period:
                    self.nav = (step.location, step.edge)
                    self.phase, self.phase_time = 'await_oplop', now
            elif self.phase == 'await_oplop':  # until navigation has left the last 0BH
                if nav.get('lost') == 0:
                    self.phase = 'navigating'
            elif self.phase == 'navigating':
                if nav.get('at_location') == 1 and nav.get('lost') == 0:
                    self.phase = 'positioning'  # 03H: Position has speed control
                    self.positioning_distance = 0.0
                elif arrived:
                    self.phase, self.phase_time = 'settling', now
        elif step.kind == 'next_marker':
            if self.phase == 'wait_positioning' and nav.get('lost') == 0:
                self.phase, self.positioning_distance = 'positioning', 0.0
        elif step.kind in ('load', 'unload'):
            load = self.status.get('load') or {}
            if load.get('job') == self.load['job']:
                if load.get('state') == 'done':
                    self.load = {**self.load, 'action': 'idle'}
                    self._advance(now)
                elif load.get('state') == 'failed':
                    self.load = {**self.load, 'action': 'stop'}
                    self._fail(now, 'load_failed', 'load', load.get('cause', ''))
        elif step.kind == 'wait':
            if now - self.phase_time >= step.value:
                self._advance(now)
        elif step.kind == 'srm_landing':  # an SRM begun on departure: wait for the landing
            route = self.status.get('route') or {}
            if route.get('manoeuvre') == self._srm_manoeuvre and \
                    route.get('state') == 'following' and now - self.phase_time > 0.5:
                self._advance(now)
        elif step.kind == 'srm':
            route = self.status.get('route') or {}
            if self.phase == 'wait_landmark' and self.route['mode'] == 'srm':
                self.phase = 'srm'
            elif self.phase == 'srm' and route.get('manoeuvre') == self._srm_manoeuvre and \
                    route.get('state') == 'following':
                self._advance(now)
        elif step.kind == 'pass':
            if self.phase == 'passed':
                self._advance(now)
        elif step.kind == 'continue':
            if now - self.phase_time >= 0.5:
                self._advance(now)
        elif step.kind == 'manual':
            if step.value and now - self.phase_time >= step.value:
                self._advance(now)  # route_command idle: the motors off
        elif step.kind == 'calibrate':  # done once route following has read its frames
            state = (self.status.get('route') or {}).get('state')
            if self.phase == 'start' and state == 'calibrating':
                self.phase = 'calibrating'
            elif self.phase == 'calibrating' and state == 'idle':
                self._advance(now)
        elif step.kind in TAPE_STEPS:
            outcome, self.route = self.tape.update(self.status.get('route') or {}, self.route, now)
            for line in self.tape.log:
                self._log(now, line)
            self.tape.log.clear()
            if outcome.state == 'done':
                self._advance(now)
            elif outcome.state == 'failed':
                self._fail(now, outcome.cause, 'route', outcome.detail, report=outcome.report)

    def _log(self, now: float, text: str) -> None:
        self.notes.add(now, text)

    # -- the loop ---------------------------------------------------------------------------
    def tick(self, now: float) -> dict[str, dict[str, Any]]:
        """Supervise, run the step, and send every command record (pigeon-holes)."""
        traction = self.status.get('traction') or {}
        # Over the time since the last pass, not one period: under sim time a pass can come
        # late or be skipped (a starved process), and period x speed then loses distance (a
        # missing stop marker can be overrun by 13.8 m against the 4 m positioning limit).
        dt = self.p.period if self._last_tick is None else min(max(now - self._last_tick, 0.0),
                                                                 1.0)
        self._last_tick = now
        travelled = abs(traction.get('speed', 0)) / 1000.0 * dt
        self.distance += travelled
        self.distance_since_landmark += travelled
        self.positioning_distance += travelled
        if self.mode == 'cruising':
            self.distance = self.distance_since_landmark  # no goal: progress is landmarks
        if self.mode in ('running', 'cruising'):
            self._supervise(now)
            if traction.get('tripped') and now - self.task_start < self.p.trip_grace \
                    and now - self.arm_until > 3 * self.p.period:
                # Still tripped after 00H-then-demand: traction missed it (a trip while
                # tripped restarts its latch). Arm again while the start-up grace lasts.
                self.arm_until = now + 2 * self.p.period
        if self.mode == 'running':
            self._run_step(now)
        self._update_pause(now)
        route = self.status.get('route') or {}
        if self.route['mode'] == 'srm' and route.get('manoeuvre') == self.route['manoeuvre'] \
                and route.get('state') == 'following':
            self.route = {**self.route, 'mode': 'follow_wire'}  # the SRM has landed
        return self._commands(now)

    def _commands(self, now: float) -> dict[str, dict[str, Any]]:
        """Every command record as things stand (the pigeon-holes)."""
        demand = 0 if self.held(now) else self.demand
        if demand and (self.slow or self.route['mode'] == 'srm'):
            demand = min(demand, self.p.srm_demand)
        priority = 0
        if self.p.speed_request_path == 'via_executive' and demand:
            request = (self.status.get('navigation') or {}).get('speed_request', 0x40)
            priority = 1
            if not request & 0x40:  # navigation asks for control: forward its request
                speed = request & 0x1F
                # 0 would be an emergency stop; 1 % is below breakaway
                demand = (-speed if request & 0x20 else speed) or 1
        demand, priority = self._paused_drive(demand, priority)
        return {
            'traction_command': {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': demand,
                                 'executive_priority': priority},
            'navigation_command': {'task_location': self.nav[0], 'stop_marker': self.nav[1]},
            'route_command': dict(self.route),
            'load_command': dict(self.load),
            'comms_command': {'task_id': self.task_id, 'state': self.report['state'],
                              'pause': self.pause,
                              'step': self.index if self.mode == 'running' else 0,
                              'cause': self.report['cause'], 'subsystem': self.report['subsystem'],
                              'detail': self.report.get('detail', 'none'),
                              **{key: self.report.get(key, default)
                                 for key, default in NO_BRANCH_FIELDS.items()},
                              'location': self.last_marker if self.last_marker <= 31 else 0xFF},
        }
