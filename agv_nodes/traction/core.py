"""The Traction sub-processor: the 1983 speed-control program, its trips, and a closed loop.

`open_loop_1983` is the listing of Baker 1983, App. B.2 as a state machine on the loop clock: START
= MONO, GETREF, SENSOR, MONO, SUM, COMP, the Z-80's blocking waits (the "runout" after a limited
step, the two FLIP waits, the field build-up after reset) as timed states during which MONO keeps
retriggering the trip relay:

* GETREF: manual (command byte 1 bit 0) takes byte 1 whole as the signed REF before any other check
  (bypassing the emergency and the radio stop); auto with byte 2 = 00H gives REF = -5 % (plug
  braking, "emergency stop"); then the radio stop (armature off, DCYCLE := 0, re-poll); then the
  source: the executive (byte 2) or the Position link (A := port & 3FH, NEG if bit 5).
* SENSOR: SPEED := DCYCLE (open loop, SPDTAB is the identity).
* SUM: ERROR := REF - SPEED limited to +-16 % (`arithmetic`: `saturating`, the intent, or
  `faithful_8bit`, the listing's mod-256 wrap, App. B.2.2).
* COMP: DCYCLE := SPEED + ERROR clamped to +-80; a sign against the field direction runs FLIP
  (armature and field off, wait, toggle, field on, wait); armature off at demand 0 (coast), else
  CTC1 := |DCYCLE| and armature on; a limited step waits `runout_wait`.

Waits: the prose says 200 ms (runout) and 100 ms (FLIP halves, field build-up), B.2.2's delay
formula 100 and 50 ms (6.3 against App. B.2.2); both are parameters, the prose the default.

Trip relay (modern): traction opens the contactor (drive and field off) and latches when its loop
stalls, the executive's command is older than `command_timeout`, the Position link it obeys older
than `link_timeout`, or a command/link record is corrupt; it also starts tripped. Only a valid
command with byte 2 = 00H, then one non-zero, clears it. While it is open, traction_status shows
`emergency_stop` = 1 once a 00H has been taken (the latch is armed): a writer cannot know
otherwise whether its 00H arrived, since what it sends before traction's reader has matched it
is lost (docs/hardware.md, "Starting a board: the start-up contract").

`closed_loop` (the default; beyond 1983: B.2's skeleton with a speed sensor): REF is a speed demand
through the open-loop map v = (|REF| - 5) / 75 m/s (6.3.2), shaped by acceleration and jerk limits,
and a PI loop on wheel odometry sets the duty. Navigation's controlled stop (8.5) needs it; it
holds 0.200 m/s at 20 % loaded or not (open loop: 0.195/0.161; bench/traction_bench.py).
"""

from typing import Any

from agv_nodes.odometry import Odometer
from agv_nodes.records.ports import CORRUPT, DUPLICATE_WRITER
from agv_nodes.subsystem import SubsystemCore
from agv_nodes.traction.settings import TractionParams


def _signed8(value: int) -> int:
    value &= 0xFF
    return value - 256 if value & 0x80 else value


class TractionCore(SubsystemCore):
    """See the module docstring. Inputs by record; outputs traction_drive / traction_status."""

    node, settings_type, period_setting = 'traction', TractionParams, 'loop_period'

    def __init__(self, params: TractionParams | None = None) -> None:
        super().__init__(params)
        # ADATA (PIO1-A): bit 7 armature disable, bit 6 field disable, bit 5 field forward.
        self.armature_off = self.field_off = True
        self.field_forward = False  # INIT leaves bit 5 = 0
        self.ref = self.speed = self.error = 0  # REF, SPEED, ERROR (%)
        self.dcycle = self.dcdem = 0  # signed %; |duty| loaded into CTC1
        self.source = 'trip'
        self.manual = self.estop = self.radio = self.bumper = False
        self.watchdog = 0
        self.state = 'start'  # start | run | flip_decay | flip_build | runout
        self.wait_until = 0.0
        self.tripped = True
        self.trip_cause = 'startup'
        self._reset_stage = 0  # 0: wait for byte 2 = 00H; 1: wait for byte 2 != 00H
        self.command: dict[str, Any] | None = None
        self.link: dict[str, Any] | None = None
        self.command_time = self.link_time = -1e9
        self._odometry_count = 0
        self._odometry_at: dict[str, int] = {}
        self.measured_speed = 0.0  # m/s from wheel odometry
        self._last_tick: float | None = None
        self._next_status = self._v_demand = self._a_demand = self._integral = 0.0
        self.odometer = 0.0  # m travelled, from the wheel distance counters
        self._wheels = Odometer()
        self._braking = False
        self.stop_target: float | None = None  # odometer reading of a requested stop

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """Take an accepted traction_command, traction_link or wheel_odometry record."""
        if record == 'traction_command':
            self.command, self.command_time = fields, now
            if self.tripped:
                self._advance_reset(fields)
            elif self.p.emergency_stop == 'immediate' and self._estop_demanded() \
                    and not self.armature_off and self.dcdem:
                # Armature off the moment 00H arrives, not up to two /clock steps later at the
                # next pass, which brakes (plug braking; the closed loop's hardest braking).
                self._cut_armature(now)
                return {'traction_drive': self.drive()}
        elif record == 'traction_link':
            news = fields != self.link
            self.link, self.link_time = fields, now
            if stop_in := fields.get('stop_in', 0):  # a controlled stop, in the link's direction
                way = -1.0 if fields['reverse'] else 1.0
                self.stop_target = self.odometer + way * stop_in / 1000.0
            else:
                self.stop_target = None
            if news and self.p.link_reaction == 'at_once' and self.p.control == 'closed_loop' \
                    and self._last_tick is not None:
                self._odometry_at[record] = self._odometry_count
                return self.tick(now)  # a pass now, not at the next loop (see link_reaction)
        elif record == 'wheel_odometry':
            self.measured_speed = (fields['left_speed'] + fields['right_speed']) / 2000.0
            self._odometry_count += 1
            # The encoders' own distance, not speed x tick (agv_nodes.odometry).
            self.odometer = self._wheels.update(fields['left_distance'], fields['right_distance'])
        if record in ('traction_command', 'traction_link'):
            self._odometry_at[record] = self._odometry_count
        return None

    def _stale(self, record: str, age: float, timeout: float) -> bool:
        since = self._odometry_count - self._odometry_at.get(record, 0)
        return age > timeout and (since >= self.p.stale_confirm or age > 2 * timeout)

    def on_reject(self, record: str, reason: str, now: float) -> dict | None:
        """Take a record the reader refused: corrupt command or link bytes trip the relay.

        So does a duplicate writer of any input (two live endpoints both writing as its named
        writer, records.writer_check): neither can be trusted, and the drive goes off at once.
        """
        if record in ('traction_command', 'traction_link') and reason in CORRUPT:
            self._trip('corrupt_record')
        elif reason == DUPLICATE_WRITER:
            self._trip(DUPLICATE_WRITER)
            return {'traction_drive': self.drive()}
        return None

    def on_radio_stop(self, on: bool, now: float) -> None:
        """Set the radio-control stop input (PIO1-A bit 4, high = stop)."""
        self.radio = bool(on)

    def on_bumper(self, on: bool, now: float) -> None:
        """Set the bumper input (hw/bumper): pressed by another truck, the armature goes off.

        Modern: a fleet's trucks can touch. The switch acts as the radio stop does, and is
        reported apart, so that a collision is never taken for an operator's stop.
        """
        self.bumper = bool(on)

    def _advance_reset(self, fields: dict[str, Any]) -> None:
        if fields['manual']:
            return
        if fields['demand'] == 0:
            self._reset_stage = 1
        elif self._reset_stage == 1:
            self.tripped, self.trip_cause, self._reset_stage = False, 'none', 0
            # restart at BEGIN: INIT (field bit 5 = 0), build-up wait
            self.state, self.field_forward, self.wait_until = 'start', False, 0.0

    def _armed(self) -> bool:
        """Tripped, with a 00H taken: the next non-zero demand closes the relay."""
        return self.tripped and self._reset_stage == 1

    def on_clock_jump(self, text: str, now: float) -> None:
        """Open the relay on a jump of the genuine /clock (agv_nodes/clock_jump.py), named so.

        Else the command would trip it as stale_command, blaming a silent executive.
        """
        self._trip('clock_jumped')
        self.clock_jump = text

    def _trip(self, cause: str) -> None:
        if not self.tripped:
            self.trip_cause = cause
        self.tripped, self._reset_stage = True, 0
        self.armature_off = self.field_off = True
        self.dcycle = self.dcdem = 0
        self.source, self.state = 'trip', 'start'
        self._v_demand = self._a_demand = self._integral = 0.0

    # -- the loop ---------------------------------------------------------------------------
    def tick(self, now: float) -> dict[str, dict[str, Any]]:
        """One pass of the program (or of a wait), then the outputs."""
        if self._last_tick is not None and now - self._last_tick > self.p.stall_limit:
            self._trip('stalled_loop')
        dt = self.p.loop_period if self._last_tick is None else now - self._last_tick
        self._last_tick = now
        self.watchdog = (self.watchdog + 1) & 0xFF  # MONO, also inside every WAIT1
        if not self.tripped:
            if self._stale('traction_command', now - self.command_time, self.p.command_timeout):
                self._trip('stale_command')
            elif (self._position_has_priority()
                  and self._stale('traction_link', now - self.link_time, self.p.link_timeout)):
                self._trip('stale_link')
        if (not self.tripped and self.p.control == 'open_loop_1983'
                and self.p.emergency_stop == 'immediate' and self._estop_demanded()
                and self.dcycle > 0):  # the armature off now, not after the slew
            self._cut_armature(now)
        if not self.tripped and now >= self.wait_until:
            if self.p.control == 'closed_loop':
                self._closed_loop(now, dt)
            else:
                self._program(now)
        out = {'traction_drive': self.drive()}
        if now >= self._next_status:
            self._next_status = now + self.p.status_period
            out['traction_status'] = self.status()
        return out

    def health(self) -> tuple[int, str]:
        """For /diagnostics: the trip relay (ERROR when a fault opened it, WARN at start-up)."""
        if not self.tripped:
            return 0, ''
        hint = {'stale_command': ' (the executive is silent)',
                'stale_link': ' (navigation is silent)',
                'duplicate_writer': ' (two writers of one input: its row names them)',
                'clock_jumped': f' ({getattr(self, "clock_jump", "")})'}.get(self.trip_cause, '')
        return (1 if self.trip_cause == 'startup' else 2,
                f'trip relay open: {self.trip_cause}{hint}')

    def _cut_armature(self, now: float) -> None:
        """Emergency stop `immediate`: armature off and duty 0 now, any wait abandoned."""
        self.armature_off = True
        self.dcycle = self.dcdem = self.speed = 0
        self.state, self.wait_until = 'run', now

    def _estop_demanded(self) -> bool:
        cmd = self.command
        return cmd is not None and not cmd['manual'] and cmd['demand'] == 0

    def _position_has_priority(self) -> bool:
        cmd = self.command
        if cmd is None or cmd['manual'] or cmd['demand'] == 0 or cmd['executive_priority']:
            return False
        return self.link is not None and not self.link['executive_priority']

    def _field_wait(self, now: float, forward_at_start: bool) -> bool:
        """Run BEGIN/INIT's and FLIP's timed field waits; True when this pass was one.

        INIT leaves the field reversed in the listing; the closed loop starts it forward.
        """
        if self.state == 'start':
            self.field_off, self.armature_off, self.state = False, True, 'run'
            self.field_forward = self.field_forward or forward_at_start
        elif self.state == 'flip_decay':
            self.field_forward, self.field_off = not self.field_forward, False
            self.state = 'flip_build'
        else:
            return False
        self.wait_until = now + self.p.field_wait
        return True

    def _program(self, now: float) -> None:
        """Continue the listing from where its last wait left it."""
        if self._field_wait(now, forward_at_start=False):
            return
        if self.state == 'flip_build':
            self._comp_tail(now)
            return
        self.state = 'run'  # after runout, or a fresh pass
        if not self._getref():
            return
        self.speed = self.dcycle  # SENSOR: SPDTAB identity (open loop)
        self._sum()
        self._comp(now)

    def _getref(self) -> bool:
        """GETREF; False while the radio stop holds the program in its re-poll loop."""
        cmd = self.command or {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': 0,
                               'executive_priority': 0}
        self.manual = bool(cmd['manual'])
        self.estop = False
        if self.manual:  # byte 1 whole, before any other check
            self.ref = _signed8(cmd['manual'] | cmd['manual_speed'] << 1 | cmd['reverse'] << 7)
            self.source = 'manual'
        elif cmd['demand'] == 0:
            self.ref, self.estop, self.source = self.p.estop_ref, True, 'emergency_stop'
        elif self.radio or self.bumper:
            self.armature_off, self.dcycle = True, 0
            self.source = 'bumper' if self.bumper else 'radio_stop'
            return False
        elif cmd['executive_priority'] or self.link is None or self.link['executive_priority']:
            self.ref, self.source = cmd['demand'], 'executive'
        else:
            a = self.link['speed'] | self.link['reverse'] << 5  # port & 3FH (bit 6 = 0 here)
            self.ref, self.source = -(a & 0x1F) if a & 0x20 else a, 'position'
        return True

    def _sum(self) -> None:
        e = self.ref - self.speed
        e = _signed8(e) if self.p.arithmetic == 'faithful_8bit' else e
        self.error = max(-self.p.step_limit, min(self.p.step_limit, e))

    def _comp(self, now: float) -> None:
        d = self.speed + self.error
        if d >= 0:
            d = min(d, self.p.max_duty)
            self.dcycle = self.dcdem = d
            flip = not self.field_forward  # the field must be forward, also for d = 0
        else:
            d = max(d, -self.p.max_duty)
            self.dcycle, self.dcdem = d, -d
            flip = self.field_forward
        if flip:  # FLIP: armature and field off, DCYCLE := 0, wait
            self.armature_off = self.field_off = True
            self.dcycle, self.state, self.wait_until = 0, 'flip_decay', now + self.p.field_wait
            return
        self._comp_tail(now)

    def _comp_tail(self, now: float) -> None:
        self.state = 'run'
        if self.dcdem == 0:
            self.armature_off = True  # coast: friction only
            return
        self.armature_off = False  # CTC1 := DCDEM; armature on
        if abs(self.error) == self.p.step_limit:
            self.state, self.wait_until = 'runout', now + self.p.runout_wait

    # -- closed loop (beyond 1983) -------------------------------------------------------------
    def _closed_loop(self, now: float, dt: float) -> None:
        if self._field_wait(now, forward_at_start=True):
            return
        self.state = 'run'
        if not self._getref():
            self._v_demand = self._a_demand = self._integral = 0.0
            return
        p = self.p
        if self.estop:  # emergency stop: demand zero at once, brake as hard as allowed
            target = self._v_demand = self._a_demand = 0.0
        else:
            target = max(0.0, abs(self.ref) - p.dead_band) * p.v_per_percent
            target = target if self.ref >= 0 else -target
        if self.source == 'position' and self.stop_target is not None and target != 0.0:
            # Controlled stop (thesis 8.5): follow v = sqrt(2 a d) down to the stop point and
            # cut the drive once the coast-down distance covers what is left.
            way = 1.0 if target > 0 else -1.0
            remaining = way * (self.stop_target - self.odometer)
            speed = abs(self.measured_speed)
            if remaining <= speed * speed / (2.0 * p.coast_decel) or remaining <= 0.0005:
                self._v_demand = self._a_demand = self._integral = 0.0
                self.dcycle, self.dcdem, self.armature_off = 0, 0, True
                return
            profile = (2.0 * p.stop_decel * remaining) ** 0.5
            if profile < abs(target):
                target = way * profile
                self._v_demand = target  # the profile is the demand (no extra ramp)
        # Jerk- and acceleration-limited ramp of the speed demand toward the target.
        gap = target - self._v_demand
        stop_dist_a = self._a_demand * abs(self._a_demand) / (2 * p.max_jerk)
        slowing = abs(target) < abs(self._v_demand)
        limit = p.max_decel if slowing else p.max_accel
        want_a = max(-limit, min(limit, (gap - stop_dist_a) * 4.0))
        da = max(-p.max_jerk * dt, min(p.max_jerk * dt, want_a - self._a_demand))
        self._a_demand += da
        step = self._a_demand * dt
        self._v_demand = (min(self._v_demand + step, target) if gap > 0
                          else max(self._v_demand + step, target))
        error = self._v_demand - self.measured_speed
        way = 1.0 if (self._v_demand or self.measured_speed) >= 0 else -1.0
        overspeed = -way * error  # how much faster than asked, in the direction of travel
        # Braking latch: enter above brake_margin, leave once at (or below) the demand, so the
        # field is not flipped back and forth (each FLIP costs two field waits).
        if overspeed > p.brake_margin and abs(self.measured_speed) > 0.05:
            self._braking = True
        elif overspeed <= 0.0 or abs(self.measured_speed) <= 0.05:
            self._braking = False
        if self._braking:
            # Braking mode: plug braking (reverse field) in proportion to the overspeed; the
            # 1983 truck had only friction and this reverse-field hold (thesis 8.5).
            self._integral = 0.0
            duty = -way * min(p.max_duty, p.brake_gain * overspeed)
        else:
            self._integral = max(-1.0, min(1.0, self._integral + error * dt))
            feed = (p.dead_band + abs(self._v_demand) / p.v_per_percent) if self._v_demand \
                else 0.0
            duty = (feed if self._v_demand >= 0 else -feed) + p.kp * error + \
                p.ki * self._integral
        if target == 0.0 and abs(self._v_demand) < 1e-3 and abs(self.measured_speed) < 0.02:
            duty, self._integral = 0.0, 0.0  # at rest: no hold current
        duty = max(-p.max_duty, min(p.max_duty, round(duty)))
        if (duty > 0) != self.field_forward and duty != 0 and abs(duty) < p.flip_hysteresis:
            duty = 0  # a small demand against the field: coast rather than flip the field
        if duty != 0 and (duty > 0) != self.field_forward:
            self.armature_off = self.field_off = True
            self.dcycle = self.dcdem = 0
            self.state, self.wait_until = 'flip_decay', now + p.field_wait
            return
        self.dcycle = self.speed = int(duty)
        self.dcdem = abs(self.dcycle)
        self.armature_off = self.dcdem == 0

    # -- outputs ----------------------------------------------------------------------------
    def drive(self) -> dict[str, Any]:
        """Return the traction_drive record (what the motor controller board is told)."""
        on = not self.tripped
        return {
            'armature_duty': self.dcdem if on and not self.armature_off else 0,
            'field_duty': self.p.field_duty if on and not self.field_off else 0,
            'armature_enable': int(on and not self.armature_off),
            'field_enable': int(on and not self.field_off),
            'field_forward': int(self.field_forward), 'contactor': int(on),
            'watchdog': self.watchdog,
        }

    def status(self) -> dict[str, Any]:
        """Return the traction_status record."""
        return {
            'ref': max(-128, min(127, self.ref)), 'duty': self.dcycle,
            'emergency_stop': int(self.estop and not self.tripped or self._armed()),
            'radio_stop': int(self.radio),
            'bumper': int(self.bumper),
            'tripped': int(self.tripped), 'manual': int(self.manual),
            'field_forward': int(self.field_forward),
            'armature_on': int(not self.tripped and not self.armature_off),
            'reversing': int(self.state in ('flip_decay', 'flip_build')),
            'source': self.source if not self.tripped else 'trip',
            'trip_cause': self.trip_cause if self.tripped else 'none',
            'speed': int(max(-32768, min(32767, round(self.measured_speed * 1000)))),
        }
