"""The executive's supervision: stale, rejected and faulty sub-systems end in a stop.

A mixin of ExecutiveCore (agv_nodes.executive.core), kept apart because it is the safety half of
the executive: every fault here ends the task with an emergency stop and a named cause.
"""

from typing import Any

from agv_nodes.executive.itinerary import NO_TASK
from agv_nodes.executive.tape_legs import no_branch_detail

STATUS_RECORDS = {'navigation': 'navigation_status', 'traction': 'traction_status',
                  'route': 'route_status', 'load': 'load_status',
                  'communications': 'comms_status'}
SUBSYSTEM_OF = {record: sub for sub, record in STATUS_RECORDS.items()}
# The sub-systems each truck has: the 1983 tug's five boards, the 1991 CONCIC-II's camera
# route following and its link to the outside.
SUBSYSTEMS = {'wire': ('navigation', 'traction', 'route', 'load', 'communications'),
              'camera': ('route', 'communications')}


class FaultSupervision:
    """Supervision and the emergency stop (see the module docstring)."""

    def supervise(self, now: float) -> dict[str, dict[str, Any]] | None:
        """Check for a stale status between two passes; on a fault send the e-stop at once.

        The sub-systems report on the same 50 ms grid, so their records arrive together, and a
        status that goes stale between two arrivals would otherwise wait for the next pass.
        """
        if self.mode not in ('running', 'cruising'):
            return None
        self._supervise(now)
        return self._commands(now) if self.mode == 'failed' else None

    def on_clock_jump(self, text: str, now: float) -> dict[str, dict[str, Any]] | None:
        """Fail the task on a jump of the genuine /clock (agv_nodes/clock_jump.py) and stop.

        The clock's fault, named so: the node's time is held across the jump, so no status
        looks stale for it. No task, nothing moves: /diagnostics says it (clock_watch).
        """
        if self.mode not in ('running', 'cruising'):
            return None
        self._fail(now, 'clock_jumped', 'world', text)
        return self._commands(now)

    # (when, sub-system) of the last status record a duplicate writer sent (two live endpoints
    # both writing as one status's writer: records.writer_check), None before any
    duplicate: tuple[float, str] | None = None

    def on_duplicate_writer(self, record: str, now: float) -> dict[str, dict[str, Any]] | None:
        """Hear that a status comes from two live writers at once: a fault, stop now."""
        self.duplicate = (now, SUBSYSTEM_OF.get(record, 'none'))
        return self.supervise(now)

    def _supervise(self, now: float) -> None:
        # A duplicate writer first: every record of either is rejected (the reader's), so the
        # status also goes stale, and two processes writing it is the better name. It stands
        # while its records keep coming (1 s, as the rejection budget's window).
        if self.duplicate is not None and now - self.duplicate[0] <= 1.0:
            return self._fail(now, 'duplicate_writer', self.duplicate[1],
                              'its status comes from two live writers (see its inputs row)')
        # Then: a writer whose records are being rejected also goes stale, and the rejections
        # are the better name for it.
        if self.rejects:
            self.rejects = [(t, sub) for t, sub in self.rejects if now - t <= 1.0]
        p = self.p
        if len(self.rejects) > p.reject_limit:
            writers = sorted({sub for _t, sub in self.rejects})
            return self._fail(now, 'rejected_records', writers[0] if len(writers) == 1
                              else 'none', f'{len(self.rejects)} in 1 s')
        # Communications too: a silent sub-system is a fault to stop on (Baker 1983, 7.2: one
        # that failed made the others reset, which hid the fault), and without it no abort
        # reaches the truck. Its status comes on the same 50 ms grid as the others.
        status_time, max_age, timeout = self.status_time, self.max_age, p.status_timeout
        for sub in self.subsystems:
            t = status_time.get(sub)
            if t is None:
                if now - self.task_start > 1.0:
                    return self._fail(now, 'stale_status', sub, 'never heard from')
                continue
            age = now - t
            if age > max_age.get(sub, -1.0):  # max(), without its call at 200 Hz
                max_age[sub] = age
            if age > timeout and (self.arrivals - self.arrivals_at.get(sub, 0) >= p.stale_confirm
                                  or age > 2 * timeout):
                return self._fail(now, 'stale_status', sub, f'{age:.2f} s old')
        nav = self.status.get('navigation') or {}
        if nav.get('sensor_lost'):
            return self._fail(now, 'sensor_lost', 'navigation', 'marker sensor lost')
        route = self.status.get('route') or {}
        fault = route.get('drive_fault', 'none')
        if fault != 'none':  # the CONCIC-II's safety supervisor (Rajagopalan 1991, 6.3.11)
            return self._fail(now, 'drive_fault', 'route', fault.replace('_', ' '), fault)
        if route.get('state') == 'lost' and not self._lost_before_start(now):
            if self.camera:
                return self._fail(now, 'lost_track', 'route', 'tape lost')
            return self._fail(now, 'lost_wire', 'route', 'guide wire lost')
        if route.get('state') == 'unheard' and now - self.task_start > self.p.trip_grace:
            return self._fail(now, 'lost_wire', 'route',
                              f'guide-wire pickup not heard within {self.p.trip_grace:g} s')
        if route.get('state') == 'no_branch' and self.camera:
            account = self.tape.no_branch(route)
            return self._fail(now, 'no_branch', 'route', no_branch_detail(account), report=account)
        traction = self.status.get('traction') or {}
        if traction.get('bumper'):
            return self._fail(now, 'collision', 'traction',
                              'bumper pressed (another truck or an obstacle)')
        if traction.get('radio_stop'):
            return self._fail(now, 'radio_stop', 'traction', 'radio stop')
        if traction.get('trip_cause') == 'clock_jumped':  # traction took the jump first
            return self._fail(now, 'clock_jumped', 'world', 'traction tripped on it')
        if traction.get('trip_cause') == 'duplicate_writer':  # two writers of its inputs
            return self._fail(now, 'duplicate_writer', 'traction',
                              'one of its inputs comes from two live writers (its inputs row)')
        if traction.get('tripped') and now - self.task_start > self.p.trip_grace:
            return self._fail(now, 'tripped', 'traction', traction.get('trip_cause', ''))
        if self.distance > self.p.route_limit:
            return self._fail(now, 'route_limit', 'navigation',
                              f'{self.distance:.1f} m without reaching the step goal')
        if self.phase == 'positioning' and self.positioning_distance > self.p.positioning_limit:
            return self._fail(now, 'route_limit', 'navigation',
                              f'no stop marker within {self.positioning_distance:.1f} m')
        return None

    def _lost_before_start(self, now: float) -> bool:
        """Hold, not fail, on a LOST the route said before the task began (within trip_grace).

        It may be a pickup stream that stalled while the truck stood (a starved process on the
        wall clock), which the route clears at rest once the wire is back. The truck is held at
        00H until the route's next status, which fails the task if the wire is still gone.
        """
        if self.status_time.get('route', now) >= self.task_start \
                or now - self.task_start > self.p.trip_grace:
            return False
        self.arm_until = max(self.arm_until, now + 2 * self.p.period)
        return True

    def held(self, now: float) -> bool:
        """Return True while traction's demand must be 00H whatever the task asks.

        While arming traction (00H then a demand), and while route following has not yet heard
        its guide-wire pickup: a task that arrives as the world starts to move meets a route
        whose pickup stream has not reached it yet. Such a route says unheard, not lost; the
        truck stands until it is heard, and _supervise fails the task if it stays silent for
        trip_grace after the task began.
        """
        return now < self.arm_until or (self.status.get('route') or {}).get('state') == 'unheard'

    def _fail(self, now: float, cause: str, subsystem: str, detail: str,
              drive_fault: str = 'none', report: dict[str, Any] | None = None) -> None:
        """Stop and fail the task; `drive_fault` is comms_command's detail (cause drive_fault).

        `report`: more of comms_command's fields of the failure (a no_branch's junction, sign
        and decision), so that the report line names them too.
        """
        self._stop_everything()
        self.mode = 'failed'
        self.fault = (cause, subsystem)
        self.report = {'state': 'failed', 'cause': cause, 'subsystem': subsystem,
                       'detail': drive_fault, **(report or {})}
        self._log(now, f'task {self.task_id}: FAILED {cause} ({subsystem}): {detail}')

    def _stop_everything(self) -> None:
        self.demand = 0  # EMERGENCY STOP: traction byte 2 = 00H
        self.nav = (NO_TASK, 0)
        self.load = {**self.load, 'action': 'stop'}
        self.slow = False
        self._srm_at = self._srm_pending = None
        if self.route['mode'] == 'srm':  # keep steering on the wire while the truck stops
            self.route = {**self.route, 'mode': 'follow_wire'}
        if self.camera:  # the CONCIC-II stops by motor-off (Rajagopalan 1991, 7.3.4)
            self.route = {**self.route, 'mode': 'idle'}

