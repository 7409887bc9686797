"""Camera mode of route following: the CONCIC-II's legs along floor tape (Rajagopalan 1991).

A leg begins when camera mode is entered or route_command carries a new `leg` value; its
`direction` is read then (a change within a leg waits for the next one, so the truck is never
thrown from cruise one way to cruise the other). A leg counts its road signs (`junctions`) and
the axle centre's travel (`distance`, the sum of |travel| by wheel odometry, so a spin adds
nothing and a reverse leg counts up), both from 0. Forwards the front camera leads, in reverse
the rear one: camera_law.py steers by it (or by both cameras) and gives the wheel speeds. A leg
may choose its camera (route_command camera): front, rear or both either way, a camera facing
against travel steering from behind the axle (camera_select.py).

Each leading frame is analysed (camera_guidance.py), the law gives the caster angle and Eq.
5.15/5.16 the wheel speeds (Rajagopalan 1991, 5.2); a saturated frame keeps the last command.
absent_frames frames without track stop the vehicle, motor off, state no_track (4.3, App. F.5):
so a leg ends at the end of its tape. It stays stopped until the next leg. With camera_law
feed_forward and the track identified, a gap in plain tape is driven across along the identified
track for identification.gap_distance first (App. F.5: identification mode does not stop);
inside a road sign or a junction manoeuvre the stops are as ever.

Road signs (4.3, App. F.6-F.7). A sign is sighted when the track goes wide; the count goes up
then, and the decision for it is taken from route_command there and then: `junction` when
`junction_number` is 0 (the next junction) or the new count; any other number means the
executive has not kept up, and the vehicle stops (motor off, state no_branch). A branch the
sign does not offer also stops it with no_branch ("the vehicle stops with a message", App.
F.7): a turn whose branch never showed by the sign's end, or a tape that ends inside the sign.
Otherwise junction_turn.py takes the branch, holding the junction's `junction_wait` over the
crossing (state waiting); a straight choice without a wait drives on. States while at a
junction: sign (sighted, still on the tape), turning (the approach, spin and settle), waiting.
Signs are met the same way in reverse, the rear camera reading them in the frame of travel: a
reverse leg counts them and honours its decisions, left and right being those of travel. A
reverse leg's plain straight (no wait: what the executive sends for a junction its script does
not decide) is no choice among branches: a crossing met backwards, such as the main tape across
the end of a branch the truck came up, read as a T, is driven straight across, and the leg ends
where the tape does.

A leg's law going forwards is route_command's camera_law (default: the parameter's). A
dead-reckoning leg (route_command mode dead_reckoning, App. F.9) drives forwards without the
camera along `trajectory`: the stored one of that number (dead_reckoning.py) placed at the
truck's pose, or with 0 the track identified last; no such trajectory stops it at once
(no_track). Every RECKON_PERIOD the identified track's law steers by the offsets the window
would read of it (track_guidance.py), at dead_reckoning.speed; frames and road signs are not
looked at. It goes on until the executive ends the leg (route_command idle at its length).

A leg with a `length` (route_command, dm; either kind) parks there (Rajagopalan 1991, 7.3.4:
motor off from 0.16 m/s, "the recommended speed for parking", stops in 5 mm): the speed asked
for falls at turning.stop_deceleration to parking_speed parking_run before the motor-off point,
and the motors are cut once the coast from the speed the wheels report (parking_distance at
parking_speed, as the square of the speed) reaches the length: state idle, held until the next
leg. From the 0.47 m/s cruise the coast alone would run 42 mm past it. parking_speed 0 leaves
the stop to the executive, from cruise.
"""

import math
from typing import Any

import numpy as np

from agv_nodes.odometry import Odometer
from agv_nodes.route_following.camera_guidance import Measurement, Validity
from agv_nodes.route_following.camera_law import View
from agv_nodes.route_following.camera_select import SelectedCameraLaw
from agv_nodes.route_following.dead_reckoning import place, trajectory_conic
from agv_nodes.route_following.junction_turn import JunctionTurn
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.subsystem import Notes
from agv_nodes.track_geometry.fitting import Conic

# motor-off stops that hold until the next leg (drive_fault: the safety supervisor's, 6.3.11)
STOPS = ('no_track', 'no_branch', 'lost', 'drive_fault', 'parked')
# The longest camera cycle the thesis ran was 200 ms, with track identification (Rajagopalan
# 1991, 8.4.3): a leading camera silent for absent_frames such cycles is no track, as
# absent_frames empty frames are (a reverse leg without a rear camera stops at once).
LONGEST_CYCLE = 0.2  # s
# A dead-reckoning leg steers at the camera's cycle (Rajagopalan 1991, 7.5.1.6: 40-60 ms), the
# sample the feed-forward law and its gains were made for.
RECKON_PERIOD = 0.05  # s


class CameraMode:
    """See the module docstring; RouteCore delegates camera mode to it."""

    def __init__(self, params: RouteParams, notes: Notes | None = None) -> None:
        self.p = params
        self.notes = notes or Notes()
        self.law = SelectedCameraLaw(params)  # a leg's camera choice (camera_select.py)
        self.turn = JunctionTurn(params)
        self.odo = Odometer()  # each wheel's travel, from the encoders' counters
        self.rims = (0.0, 0.0)  # m/s, from wheel odometry
        self.speed = 0.0  # m/s of the axle centre, + = forwards
        self.state = 'idle'
        self.wheels = (0.0, 0.0)  # m/s asked of the rims
        self.motor_on = False
        self.steer = self.lateral = self.signal = 0.0
        self.measurement: Measurement | None = None  # the leading camera's last frame
        self.in_sign = False
        self.sign = {'left': 0, 'right': 0, 'straight': 0}
        self.leg, self.direction, self.junctions, self.travel = 0, 1, 0, 0.0
        self.length = 0.0  # m of the leg, where it parks (0: none)
        # route_command's latest (junction, junction_number, junction_wait)
        self.decision: tuple[str, int, float] = ('straight', 0, 0.0)
        self._taken: tuple[str, float] = ('straight', 0.0)  # (junction, wait) at this sign
        self._manoeuvred = False  # this sign's manoeuvre has begun
        self._set_off_at: float | None = None  # sim time the vehicle set off from rest
        self._last_lead: float | None = None  # sim time of the last leading frame
        self._rows = len(params.image.rows) or 64
        self._spun = 0.0  # m the wheels' mean moved in this spin (net), counted after it
        self.reckoning: Conic | None = None  # a dead-reckoning leg's curve, odometry frame
        self._reckoned_at: float | None = None  # sim time it last steered
        self.held = False  # held at rest by the sonar (obstacle_stop.py)

    # -- inputs -----------------------------------------------------------------------------
    def command(self, fields: dict[str, Any], now: float, entering: bool) -> bool:
        """Take a route_command in camera mode; return True when it began a leg."""
        self.decision = (fields.get('junction', 'straight'),
                         int(fields.get('junction_number', 0)),
                         float(fields.get('junction_wait', 0)))
        leg = int(fields.get('leg', 0))
        if not entering and leg == self.leg:
            return False
        trajectory = int(fields.get('trajectory', 0)) \
            if fields.get('mode') == 'dead_reckoning' else None
        self.begin_leg(leg, -1 if fields.get('direction') == 'reverse' else 1, now,
                       fields.get('camera_law', 'default'), trajectory,
                       int(fields.get('length', 0)) / 10.0, fields.get('camera', 'default'))
        return True

    def begin_leg(self, leg: int, direction: int, now: float, law: str = 'default',
                  trajectory: int | None = None, length: float = 0.0,
                  camera: str = 'default') -> None:
        """Start a leg from where the vehicle is: counts from 0, the laws afresh.

        `law`: its camera_law; `trajectory`: a dead-reckoning leg's (None: a camera leg);
        `length`: m where it parks (0: none); `camera`: its steering camera (camera_select.py).
        """
        # The identified track and the pose are those the last leg left, until law.start.
        reckoning = None if trajectory is None else self._trajectory(trajectory, now)
        if trajectory is not None:
            direction = 1  # along the trajectory as it was stored
        self.leg, self.direction, self.junctions, self.travel = leg, direction, 0, 0.0
        self.length, self._spun = length, 0.0
        self.state, self.turn.phase, self.motor_on = 'following', '', False
        self.wheels, self.in_sign, self._set_off_at, self._last_lead = (0.0, 0.0), False, None, now
        self.law.start(direction, law, camera)
        self.reckoning, self._reckoned_at = reckoning, None
        self.turn.trace.reset(self.odo, direction)
        if trajectory is not None:
            self.notes.add(now, f'leg {leg}: dead reckoning along ' + (
                f'trajectory {trajectory}' if trajectory else 'the identified track'))
            if reckoning is None:
                self._stop('no_track', now)
            return
        self.notes.add(now, f'leg {leg}: {"reverse" if direction < 0 else "forward"}, '
                            f'{self.law.describe()}'
                            + (', feed-forward' if self.law.feed_forward else ''))

    def _trajectory(self, number: int, now: float) -> Conic | None:
        """Return dead-reckoning trajectory `number` in the odometry frame; None: there is none."""
        track = self.law.track
        if number == 0:
            conic = track.fitter.implicit() if track.ready else None
            if conic is None:
                self.notes.add(now, 'dead reckoning: no track identified to go along', 'warn')
            return conic
        stored = self.p.dead_reckoning.trajectories
        if number > len(stored):
            self.notes.add(now, f'dead reckoning: no trajectory {number} '
                                f'({len(stored)} stored)', 'warn')
            return None
        return place(trajectory_conic(stored[number - 1]), *track.pose.pose)

    def leave(self) -> None:
        """Leave camera mode (idle, or the guide wire): motors off, any manoeuvre dropped."""
        self.state, self.turn.phase, self.wheels, self.motor_on = 'idle', '', (0.0, 0.0), False

    def odometry(self, fields: dict[str, Any]) -> None:
        """Take a wheel_odometry record: wheel speeds, and the leg's distance."""
        self.rims = (fields['left_speed'] / 1000.0, fields['right_speed'] / 1000.0)
        self.speed = (self.rims[0] + self.rims[1]) / 2.0
        before, left, right = self.odo.metres, self.odo.left, self.odo.right
        moved = self.odo.update(fields['left_distance'], fields['right_distance']) - before
        if self.turn.phase in ('spin', 'settle'):
            # In a spin the wheels' mean swings back and forth as one wheel's loop lags the
            # other's: summed as |travel| it added 5-8 cm a quarter turn that the axle centre
            # never went (lock step, the dynamic model). Only the spin's net move counts.
            self._spun += moved
        else:
            self.travel += abs(self._spun) + abs(moved)
            self._spun = 0.0
        self.law.odometry(self.odo.left - left, self.odo.right - right)

    def frame(self, frame: np.ndarray, now: float, camera: str) -> None:
        """Take a binary frame (1 = dark tape) from the front or the rear camera."""
        if camera == self.law.lead_camera:
            self._last_lead = now
        for view in self.law.take(frame, now, camera):
            self._view(view)

    # -- steering ---------------------------------------------------------------------------
    def _view(self, view: View) -> None:
        m = self.measurement = view.lead
        self.signal = m.rows_used / self._rows
        if self.reckoning is not None:
            return  # dead reckoning: the camera is not looked at
        if self.state in STOPS or self.turn.phase in ('wait', 'spin', 'settle'):
            return  # stopped, or the window holds still or sweeps the floor: nothing to steer by
        self._road_sign(m, view.time)
        if self.state in STOPS:
            return
        self._junction(m, view)
        speed = self.p.camera_speed
        # Only plain following may be carried across a gap: a sign or a manoeuvre stops as ever.
        theta = self.law.steer(view, speed, bridge=self.state == 'following'
                               and not (self.in_sign or self.turn.phase))
        if theta is None:
            if self.turn.phase == 'approach':
                return  # past a crossing where the tape ends: odometry takes it there
            self._stop('no_track', view.time)
            return
        self.motor_on, self.steer = True, theta
        if m.validity is not Validity.ABSENT:
            self.lateral = m.eps_d
        if m.validity is Validity.NORMAL and not (self.in_sign or self.turn.phase
                                                  or m.left_edge or m.right_edge):
            self.turn.trace.saw(m.eps_d, self.odo)  # the plain tape's line, for the approach
        if self.turn.phase == 'approach':
            return  # the manoeuvre drives to the crossing (approach_steer: how it steers)
        self.wheels = self.law.wheel_speeds(self._cruise(self._parking(speed), view.time), theta)

    def _cruise(self, speed: float, now: float) -> float:
        """Return the speed to drive at: `speed`, or less while setting off from rest."""
        if self._set_off_at is None and abs(self.speed) < 0.01 \
                and self.p.steering.set_off_acceleration > 0:
            self._set_off_at = now
        if self._set_off_at is not None:
            # Setting off from rest: our own ramp, gentler than the drive's trapezoid, which
            # accelerates both wheels alike and cannot steer while it ramps (from 40 deg off
            # the tape the window loses it before the wheels reach cruise).
            ramp = self.p.steering.set_off_acceleration * (now - self._set_off_at)
            if ramp >= speed:
                self._set_off_at = None
            speed = min(speed, ramp)
        return speed

    def _parking(self, speed: float) -> float:
        """Return `speed`, or the parking profile's less toward a length (7.3.4)."""
        p = self.p
        if not (self.length and p.parking_speed > 0):
            return speed
        ahead = self.length - p.parking_distance - p.parking_run - self.travel
        return min(speed, math.sqrt(p.parking_speed ** 2 + 2.0 * p.turning.stop_deceleration
                                    * max(ahead, 0.0)))

    def _park(self, now: float) -> bool:
        """Cut the motors where the coast ends at the length; return True once parked."""
        p = self.p
        if not (self.length and p.parking_speed > 0) or self.turn.phase:
            return False  # no length (or the executive's stop from cruise), or a manoeuvre's
        coast = p.parking_distance * (self.speed / p.parking_speed) ** 2
        if self.travel + coast < self.length:
            return False
        self._stop('parked', now)
        return True

    def _reckon(self, now: float) -> None:
        """Steer a dead-reckoning leg along its curve, every RECKON_PERIOD."""
        if self._reckoned_at is not None and now - self._reckoned_at < RECKON_PERIOD - 1e-9:
            return
        dt = RECKON_PERIOD if self._reckoned_at is None else now - self._reckoned_at
        self._reckoned_at = now
        theta = self.law.track.reckon(self.reckoning, dt)
        if theta is None:  # the curve ran out (past an open conic's end): nothing to go along
            self._stop('no_track', now)
            return
        self.motor_on, self.steer, self.lateral = True, theta, self.law.track.offsets[0]
        self.wheels = self.law.wheel_speeds(
            self._cruise(self._parking(self.p.dead_reckoning.speed), now), theta)

    def hold(self, on: bool) -> None:
        """Hold a running leg at rest for the sonar, motor off; released, set off afresh.

        Called each pass of the loop before the steering_command goes out, so no command
        drives the wheels while `on`; the set-off ramp starts where the hold ends.
        """
        self.held = on and self.state not in STOPS and self.state != 'idle'
        if self.held:
            self.motor_on, self.wheels, self._set_off_at = False, (0.0, 0.0), None

    def drive_fault(self, now: float) -> None:
        """Stop for a drive fault the safety supervisor found (Rajagopalan 1991, 6.3.11)."""
        self._stop('drive_fault', now)

    def _stop(self, state: str, now: float) -> None:
        """Motor-off stop, held until the next leg."""
        if self.state != state:
            self.notes.add(now, f'leg {self.leg}: {state} after {self.travel:.3f} m, '
                                f'{self.junctions} junction(s)',
                           'info' if state == 'parked' else 'warn')
        self.state, self.motor_on, self.wheels, self.turn.phase = state, False, (0.0, 0.0), ''

    # -- junctions (Rajagopalan 1991, 4.3, App. F.6-F.7) ------------------------------------
    def _road_sign(self, m: Measurement, now: float) -> None:
        """Branch flags while the track is wide (4.3); the junction count and its decision."""
        if m.validity is Validity.WIDE:
            if not self.in_sign:
                self._sighted(now)
            self.sign['left'] |= int(m.left_edge)
            self.sign['right'] |= int(m.right_edge)
        elif self.in_sign and m.validity is Validity.NORMAL:
            self.in_sign = False
            if self.sign['left'] or self.sign['right']:
                self.sign['straight'] = 1  # width back to normal after a turn signal
            if self._taken[0] != 'straight' and not self.turn.phase:
                self._stop('no_branch', now)  # the sign is behind us without the chosen branch
        elif self.in_sign and m.validity is Validity.ABSENT and (
                self._taken[0] == 'straight' or not self.turn.phase) \
                and not (self.direction < 0 and self._taken == ('straight', 0.0)):
            self._stop('no_branch', now)  # the tape ends at the sign, the chosen branch unseen

    def _sighted(self, now: float) -> None:
        self.in_sign, self._manoeuvred = True, False
        self.sign = {'left': 0, 'right': 0, 'straight': 0}
        self.junctions = min(self.junctions + 1, 255)
        junction, number, wait = self.decision
        self._taken = (junction, wait)
        if number not in (0, self.junctions):
            self.notes.add(now, f'junction {self.junctions}: the decision is for junction '
                                f'{number}', 'warn')
            self._stop('no_branch', now)
        elif junction != 'straight' and self.law.trailing:
            self.notes.add(now, f'junction {self.junctions}: no turn with a trailing camera',
                           'warn')
            self._stop('no_branch', now)

    def _junction(self, m: Measurement, view: View) -> None:
        """Begin the sign's manoeuvre once its branch shows; place the crossing from frames."""
        way, wait = self._taken
        if self.in_sign and not self._manoeuvred:
            if way != 'straight':
                side = way if (m.left_edge if way == 'left' else m.right_edge) else ''
            else:  # straight on: a stop over the crossing only for a wait
                side = ('left' if m.left_edge else 'right' if m.right_edge else '') \
                    if wait > 0 else ''
            if side:
                self._manoeuvred, self.state = True, 'turning'
                self.turn.begin(way, side, wait, self.direction, self.odo)
        if self.turn.phase == 'approach':
            analyser = self.law.analysers[self.law.lead_camera]
            half = analyser.normal_width * analyser.mm_col / 2.0
            self.turn.place_crossing(analyser.branch_edge(view.frame, self.turn.side), half,
                                     self.odo)

    # -- the loop ---------------------------------------------------------------------------
    def tick(self, now: float) -> None:
        """Run the junction manoeuvre at the loop rate; stop when the leading camera is silent."""
        if self.state in STOPS or self.state == 'idle':
            return
        if self._park(now):
            return
        if self.reckoning is not None:
            self._reckon(now)
            return
        if not self.turn.phase:
            silent = now - (self._last_lead if self._last_lead is not None else now)
            if silent > self.p.steering.absent_frames * LONGEST_CYCLE:
                self._stop('no_track', now)
            return
        result = self.turn.step(now, self.odo, self.rims, self.speed, self.steer, self.law)
        self.wheels, self.motor_on = self.turn.wheels, True
        if result == 'timeout':
            self._stop('lost', now)
        elif result == 'done':
            if self.turn.way != 'straight':  # on the branch: follow it afresh
                self.law.start(self.direction)
                self.turn.trace.reset(self.odo, self.direction)
                self.in_sign = False
            self.state, self._set_off_at = 'following', now
        else:
            self.state = 'waiting' if self.turn.phase == 'wait' else 'turning'

    # -- outputs ----------------------------------------------------------------------------
    def reported_state(self) -> str:
        """Return the state route_status carries: `sign` while on a sign's tape."""
        if self.held:
            return 'obstacle'
        if self.in_sign and self.state == 'following':
            return 'sign'
        return 'idle' if self.state == 'parked' else self.state  # motors off at the length

    def status(self) -> dict[str, Any]:
        """Return camera mode's route_status fields."""
        return {
            'state': self.reported_state(),
            'lateral_error': int(max(-128, min(127, round(self.lateral * 1000)))),
            'signal': int(max(0, min(255, round(self.signal * 100)))),
            'steering': int(max(-128, min(127, round(math.degrees(self.steer))))),
            'sign_left': self.sign['left'], 'sign_right': self.sign['right'],
            'sign_straight': self.sign['straight'], **self.leg_fields(),
        }

    def leg_fields(self) -> dict[str, int]:
        """Return route_status's leg fields: junctions met, distance (cm, saturating), leg."""
        return {'junctions': self.junctions, 'distance': min(round(self.travel * 100), 0xFFFF),
                'leg': self.leg}
