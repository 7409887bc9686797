"""Navigation: PC6/1's navigating and positioning loops (Baker 6.2, App. B.1).

INFO is navigation_command, OUTFO navigation_status, the link traction_link (Position -> Traction),
SAMIC/EDGIC position_sensor_command; wheel_odometry serves the controlled stop only.

* INSTRS (idle): a new INFO[0] starts navigating (OPLOP) to that location with FLAG.4 := INFO[1].0;
  a change of INFO[1] alone means "position to the next stop marker" (CLOP).
* CHK (moving): only INFO[0] is compared; a change abandons the loop and re-enters OPLOP.
* OPLOP: link 40H (the executive has speed control), OUTFO = 00H / LOCN, filter cleared with the
  location table. Every other location marker recognised is reported (OUTFO[1] := identity, then 52
  ms "move clear of it"); stop-marker centres (0EH) never are. At the task location: CLOP at once
  (first stop marker), or for the second, from the first one's centre view.
* CLOP: link 14H (Position priority, forward, 20 %), OUTFO = 03H / INFO[0], stop-view table. Each
  view sets the link to its EDGE speed byte (14H creep, 00H at the centre); at the centre OUTFO =
  0BH and the loop ends (the truck coasts to rest).

`variant = as_listed` keeps PC6/1's quirks (App. B.1): LOCN starts at 00H (the first OPLOP reports
marker 00H), and a centre view in sight when positioning starts is accepted at once (the
second-stop-marker hazard). `intended` (default) starts LOCN at FFH and, entering CLOP, ignores the
centre view until another stop view is seen.

`stopping = controlled` (Baker 1983, 8.5; the default: +-3 mm against friction_1983's +34..+55 mm,
bench/stop_bench.py): each stop view gives the distance to go (+60 ... -60 mm, 4.3, fig 4.4),
carried between views by wheel odometry; the link asks closed-loop traction to stop in it
(traction_link.stop_in); an overshoot reverses slowly onto the centre. `speed_request_path =
via_executive` (8.2.2): the request rides in navigation_status.speed_request for the executive to
forward. A quiet sensor (no status for `sensor_timeout`, or its ADC stale or saturated) makes
navigation report LOST and request speed 0.
"""

from typing import Any

from agv_nodes.markers import CENTRE_VIEW, EDIM, SLOW1, STOP_VIEWS
from agv_nodes.navigation.settings import NavigationParams
from agv_nodes.odometry import Odometer
from agv_nodes.subsystem import SubsystemCore

NO_TASK = 0xFF
AT_REST = 0.005  # m/s: below this a controlled stop counts the truck at rest


def link_byte(link: dict[str, int]) -> int:
    """Return the 1983 port value of a link record (bit 6 priority, bit 5 reverse, bits 0-4)."""
    return link['executive_priority'] << 6 | link['reverse'] << 5 | link['speed']


class NavigationCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'navigation', NavigationParams, 'period'

    def __init__(self, params: NavigationParams | None = None) -> None:
        super().__init__(params)
        self.mode = 'idle'  # idle (INSTRS) | navigating (OPLOP/SAM) | positioning (CLOP)
        # OUTFO[0] bits and OUTFO[1]: power-up record 0AH / FFH.
        self.at_location, self.slow, self.lost = 0, 1, 1
        self.last_marker, self.locstp, self.flag4 = 0xFF, NO_TASK, 0
        self.locn = 0x00 if self.p.variant == 'as_listed' else 0xFF
        self.inchk = self.info = (NO_TASK, 0)  # inchk: the last INFO pair acted on
        self.link = {'executive_priority': 0, 'reverse': 0, 'speed': 0, 'stop_in': 0}
        self.table, self.epoch, self.stop_view = 'navigating', 0, 0
        self.sensor_lost = self.input_fault = False
        self._sensor_time: float | None = None
        self._task_since: float | None = None  # first tick of a task before any sensor status
        self._seen_recognitions: int | None = None
        self._guard = False  # ignore the centre view until another view is seen
        self._next = {'status': 0.0, 'link': 0.0, 'command': 0.0}
        self._pending: dict[str, dict[str, Any]] = {}
        # controlled stopping
        self._odometer = self._speed = self._blind_until = 0.0  # _odometer: m, wheel counters
        self._wheels = Odometer()
        self._target: float | None = None  # odometer reading of the stop point
        self._rest_since: float | None = None

    # -- records out ------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """navigation_status (OUTFO plus the modern spare bytes)."""
        return {'at_location': self.at_location, 'slow': self.slow, 'reverse': 0,
                'lost': self.lost, 'last_marker': self.last_marker,
                'speed_request': link_byte(self.link), 'sensor_lost': int(self.sensor_lost),
                'input_fault': int(self.input_fault), 'stop_view': self.stop_view}

    def _locup(self) -> None:
        """LOCUP: report OUTFO to the executive now."""
        self._pending['navigation_status'] = self.status()
        self.input_fault = False

    def _set_link(self, executive: int = 0, reverse: int = 0, speed: int = 0,
                  stop_in: int = 0) -> None:
        new = {'executive_priority': executive, 'reverse': reverse, 'speed': speed,
               'stop_in': stop_in}
        if new != self.link:
            self.link = new
            if self.p.speed_request_path == 'direct_link':
                self._pending['traction_link'] = dict(new)
            else:  # via the executive: the request rides in the status record
                self._pending['navigation_status'] = self.status()

    def _select_table(self, table: str) -> None:
        """SAMIC / EDGIC: new table, filter cleared (a new epoch)."""
        self.table, self.epoch = table, (self.epoch + 1) & 0xFF
        self._pending['position_sensor_command'] = {'table': table, 'epoch': self.epoch}

    # -- the two loops ----------------------------------------------------------------------
    def _oplop(self) -> None:
        self.mode = 'navigating'
        self._select_table('navigating')
        self._set_link(executive=1)  # 40H
        self.at_location, self.slow, self.lost = 0, 0, 0  # OUTFO[0] := 00H
        if self.locn != EDIM:
            self.last_marker = self.locn
        self.stop_view, self._target = 0, None
        self._locup()

    def _clop(self, guard: bool) -> None:
        self.mode = 'positioning'
        self._set_link(speed=SLOW1)  # 14H: Position priority, forward, 20 %
        self.at_location, self.slow, self.lost = 1, 1, 0  # OUTFO[0] := 03H
        self.last_marker = self.info[0]  # OUTFO[1] := INFO[0]
        self._locup()
        self._select_table('positioning')
        self._guard = guard and self.p.variant == 'intended'
        self._target = self._rest_since = None

    def _arrived(self) -> None:
        """Centre view (or a controlled stop at rest): 0BH, then INSTRS."""
        self._set_link(speed=0)  # 00H
        self.at_location, self.slow, self.lost = 1, 1, 1  # OUTFO[0] := 0BH
        self._locup()
        self.mode, self._target = 'idle', None

    def _instrs(self) -> None:
        """INSTRS: act on a changed INFO pair while idle."""
        if self.info == self.inchk:
            return
        location, edge = self.info
        same_place = location == self.inchk[0]
        self.inchk = self.info
        if location == NO_TASK:
            return
        if same_place:  # byte 2 changed: the next stop marker
            self._clop(guard=True)
            return
        self.locstp, self.flag4 = location, edge
        self._oplop()

    def _chk(self) -> None:
        """CHK: a new INFO[0] while moving abandons the loop."""
        location, edge = self.info
        if location == self.inchk[0]:
            return
        self.inchk = self.info
        if location == NO_TASK:  # the executive withdrew the task: it takes speed control
            self.mode = 'idle'
            self._set_link(executive=1)
            return
        self.locstp, self.flag4 = location, edge
        self._oplop()

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """Handle one accepted record."""
        if record == 'navigation_command':
            self.info = (fields['task_location'], fields['stop_marker'])
            if self.mode == 'idle':
                self._instrs()
            else:
                self._chk()
        elif record == 'position_sensor_status':
            self._sensor_time = now
            self._sensor_status(fields, now)
        elif record == 'wheel_odometry':
            self._speed = (fields['left_speed'] + fields['right_speed']) / 2000.0
            # the encoders' own distance, not speed x tick (agv_nodes.odometry)
            self._odometer = self._wheels.update(fields['left_distance'], fields['right_distance'])
        return self._flush()

    def on_reject(self, record: str, reason: str, now: float) -> dict | None:
        """Flag a rejected command or sensor record in the next status."""
        self.input_fault = True
        return None

    def _sensor_status(self, fields: dict[str, Any], now: float) -> None:
        lost = bool(fields['adc_stale'] or fields['saturated'])
        if lost and not self.sensor_lost:
            self.notes.add(now, f'{now:.3f} s: sensor lost: the position sensor reports '
                           + ('no ADC snapshot' if fields['adc_stale'] else 'saturation'),
                           'warn')
        self._set_lost(lost)
        count = fields['recognitions']
        if self._seen_recognitions is None:
            # Recognitions made before we listened are history; a recognition record is news.
            self._seen_recognitions = (count - fields['recognised']) & 0xFF
        if count == self._seen_recognitions:
            return
        self._seen_recognitions = count
        if fields['table'] != self.table or fields['epoch'] != self.epoch:
            return  # a recognition from before the last SAMIC/EDGIC
        if self.mode == 'navigating':
            if now >= self._blind_until:
                self._location_seen(fields['identity'], now)
        elif self.mode == 'positioning' and fields['stop_view']:
            self._view_seen(fields['stop_view'], now)

    def _location_seen(self, identity: int, now: float) -> None:
        """Act on a recognised location (ACTION, navigating table)."""
        self.locn = identity
        if self.locn == self.locstp:
            if self.flag4 == 0:
                self._clop(guard=self.locstp == EDIM)
                return
            self.flag4 = 0
            self.locstp = EDIM  # now wait for the first stop marker's centre
        if self.locn == EDIM:
            return  # stop-marker centres are never reported
        self.last_marker = self.locn
        self._locup()
        self._blind_until = now + self.p.landmark_wait

    def _view_seen(self, view: int, now: float) -> None:
        """ACT2 (positioning table)."""
        if self._guard:
            if view == CENTRE_VIEW:
                return  # the centre we started on is still in sight
            if self.p.stopping == 'controlled' and STOP_VIEWS[view - 1][2] < 0:
                # Leaving a stop marker for the next one: its views past the centre would
                # bring a controlled stop back onto it (friction stops creep past them).
                return
            self._guard = False
        self.stop_view = view
        if self.p.stopping == 'controlled':
            _code, _speed, to_go = STOP_VIEWS[view - 1]
            # A view is first matched centre_lead mm before it is aligned (the snapshot turns
            # valid ~6 mm early), so the stop point is that much further on in the direction of
            # travel: backing up after an overshoot, centre_lead mm nearer (the forward lead
            # would put every overshooting stop 2 x 5 mm past the centre). At rest (AT_REST)
            # the way is the link's, the overshoot reverse: the measured speed (0, forward)
            # would send a truck resting 6 mm past the centre on to +11 mm.
            moving = abs(self._speed) >= AT_REST
            backing = self._speed < 0 if moving else self.link['reverse'] == 1
            lead = -self.p.centre_lead if backing else self.p.centre_lead
            self._target = self._odometer + (to_go + lead) / 1000.0
            self._rest_since = None
            self._controlled(now)
            return
        speed = STOP_VIEWS[view - 1][1]
        self._set_link(speed=speed)
        if speed == 0:
            self._arrived()

    def _controlled(self, now: float) -> None:
        """Ask traction to stop in the distance still to go (controlled stop)."""
        if self._target is None:
            return
        remaining_mm = (self._target - self._odometer) * 1000.0
        if abs(remaining_mm) < 1.0 or (abs(self._speed) < AT_REST and abs(remaining_mm) < 3.0):
            self._set_link(speed=0)
            if abs(self._speed) < 0.002:
                self._rest_since = self._rest_since if self._rest_since is not None else now
                if now - self._rest_since >= self.p.settle_time:
                    self._arrived()
            return
        self._rest_since = None
        stop_in = int(min(250, max(1, round(abs(remaining_mm)))))
        if remaining_mm > 0:
            self._set_link(speed=SLOW1, stop_in=stop_in)
        else:  # overshoot (Baker 1983, 8.5): back up slowly onto the centre
            self._set_link(reverse=1, speed=self.p.reverse_speed, stop_in=stop_in)

    def _set_lost(self, lost: bool) -> None:
        if lost == self.sensor_lost:
            return
        self.sensor_lost = lost
        if lost:
            self.lost = 1  # OUTFO bit 3: LOST
            if self.mode != 'idle':  # a new task is needed after this
                self.mode, self.inchk = 'idle', (NO_TASK, 0)
            self._set_link(speed=0)  # request speed 0
            self._locup()

    # -- the loop ---------------------------------------------------------------------------
    def tick(self, now: float) -> dict | None:
        """CHK rate: sensor watchdog, controlled stop, and the steady heartbeats."""
        if self._sensor_time is None:
            # A task and no sensor status ever: lost once quiet for sensor_timeout since the
            # task came (not at once: its first status may be on its way).
            if self.mode == 'idle':
                self._task_since = None
            elif self._task_since is None:
                self._task_since = now
            elif now - self._task_since > self.p.sensor_timeout and not self.sensor_lost:
                self.notes.add(now, f'{now:.3f} s: sensor lost: no position sensor status '
                               f'since the task came at {self._task_since:.3f} s (none '
                               'heard yet)', 'warn')
                self._set_lost(True)
        elif now - self._sensor_time > self.p.sensor_timeout and not self.sensor_lost:
            self.notes.add(now, f'{now:.3f} s: sensor lost: the last position sensor status '
                           f'came at {self._sensor_time:.3f} s', 'warn')
            self._set_lost(True)
        if self.mode == 'positioning' and self.p.stopping == 'controlled':
            self._controlled(now)
        if now >= self._next['status']:
            self._next['status'] = now + self.p.status_period
            self._pending.setdefault('navigation_status', self.status())
            self.input_fault = False
        if now >= self._next['link'] and self.p.speed_request_path == 'direct_link':
            self._next['link'] = now + self.p.link_period
            self._pending.setdefault('traction_link', dict(self.link))
        if now >= self._next['command']:
            self._next['command'] = now + self.p.command_period
            self._pending.setdefault('position_sensor_command',
                                     {'table': self.table, 'epoch': self.epoch})
        return self._flush()

    def _flush(self) -> dict | None:
        out, self._pending = self._pending, {}
        return out or None
