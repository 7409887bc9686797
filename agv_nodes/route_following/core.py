"""Route following: guide-wire steering, software-resident manoeuvres, binary-camera guidance.

Guide wire (Baker 1983, 3.5.3, 6.2.1, 7.2): the coil amplitudes give the wire's lateral offset from
the sensor point (`wire_offset`), and a PI law with a derivative term for damping steers the
Ackermann front wheels. A signal below `lost_level` for `lost_samples` samples, or no pickup sample
for that long, reports LOST at once (the executive stops the truck) until the truck is at rest with
the wire present again. A pickup that has not yet delivered a sample since the core started is
UNHEARD, not lost (modern: a graph whose world is only starting to move), and not steered by; the
executive holds the truck until it is heard, or fails the task. An SRM (mode srm, a new
`manoeuvre`) leaves the wire at the programmed steering angle until the signal drops and a wire is
found again, then follows it (7.2 task 7).

Camera (Rajagopalan 1991, mode camera, the differential-drive CONCIC-II): legs along floor tape,
forwards or backwards, steered by the leading camera or both (or, with camera_law feed_forward,
by the track identified from odometry and the camera, track_guidance.py), with road signs and
junction turns, and dead-reckoning legs along a stored trajectory (App. F.9, route_command mode
dead_reckoning, run as camera mode's legs); RouteCore hands route_command's camera fields,
wheel odometry, frames and its loop to CameraMode (agv_nodes.route_following.camera_mode),
which says what the wheels do and what status reports.
DriveSafety (drive_safety.py) checks the drive (Rajagopalan 1991, 6.3.11): on a fault camera
mode stops, motor off, and route_status names it (`drive_fault`).
ObstacleStop (obstacle_stop.py) reads the front sonar (6.3.11): an obstacle holds camera mode
at rest, motor off (state obstacle) until the way is clear; a sonar gone silent is the drive
fault sonar_silent.
Manual mode (route_command mode manual, App. F.4) drives the wheels from cmd_vel
(manual_drive.py, the same fault stopping it); calibration mode (App. F.3) reads a camera at
rest against the known tape (calibration.py).
"""

import math
from typing import Any

import numpy as np

from agv_nodes.route_following.calibration import Calibration
from agv_nodes.route_following.camera_mode import CameraMode
from agv_nodes.route_following.drive_safety import DriveSafety
from agv_nodes.route_following.manual_drive import ManualDrive
from agv_nodes.route_following.obstacle_stop import ObstacleStop
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.route_following.track_guidance import TrackGuidance
from agv_nodes.subsystem import SubsystemCore


def wire_offset(left: float, right: float, spacing: float, height: float, nominal: float) -> float:
    """Lateral offset (m, + = wire left of the sensor point) from the two coil amplitudes.

    A coil at lateral distance y from a long straight wire, height h above it, reads K / (h^2 +
    y^2), K fixed by the calibration `nominal` (a coil's reading with the wire midway), so each
    coil gives y = sqrt(K / reading - h^2); the wire is where the left coil's candidates (c -+ y_L)
    meet the right coil's (-c +- y_R). Unlike the ratio L/R this does not fold back outside the
    coils, so an SRM can capture a wire from well to one side.
    """
    if left <= 0 or right <= 0:
        return 0.0
    c, h = spacing / 2.0, height
    k = nominal * (h * h + c * c)
    y_left = math.sqrt(max(k / left - h * h, 0.0))
    y_right = math.sqrt(max(k / right - h * h, 0.0))
    # the nearest pair, the first of equals in the order (c - y_L, -c + y_R), (c - y_L,
    # -c - y_R), (c + y_L, -c + y_R), (c + y_L, -c - y_R)
    best_a, best_b = c - y_left, -c + y_right
    nearest = abs(best_a - best_b)
    for a, b in ((c - y_left, -c - y_right), (c + y_left, -c + y_right),
                 (c + y_left, -c - y_right)):
        if abs(a - b) < nearest:
            best_a, best_b, nearest = a, b, abs(a - b)
    return 0.5 * (best_a + best_b)


class RouteCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'route_following', RouteParams, 'period'

    def __init__(self, params: RouteParams | None = None) -> None:
        super().__init__(params)
        self.mode = self._state = 'idle'
        self.manoeuvre = 0
        self.srm_angle = self.lateral = self.signal = self.steer = 0.0
        self._integral = self._srm_start = 0.0
        self._prev_lateral: float | None = None
        self._weak = 0
        self._strong = 0  # consecutive samples with the wire present
        self._lost_reported = False  # a route_status with state lost has gone out
        self._srm_phase = ''
        self._found_at = -1e9
        self._wire_time: float | None = None
        self.speed = 0.0  # m/s from wheel odometry
        self._rim_speeds = (0.0, 0.0)  # m/s, from wheel odometry
        self.odometry_time: float | None = None  # sim time of the last wheel_odometry
        self.steer_actual = 0.0  # model of the actuator's position
        self.heading_error = 0.0  # SRM: heading relative to the wire left (new wire parallel)
        self._aligned_since: float | None = None
        self._lateral_rate = 0.0  # filtered d(lateral)/dt, m/s
        self._following_heading = 0.0  # heading error relative to the wire, while following
        self._next_status, self._last_state = 0.0, ''
        self.cam = CameraMode(self.p, self.notes)
        self.safety = DriveSafety(self.p.drive_safety)
        self.obstacle = ObstacleStop(self.p.obstacle, self.notes)
        self.manual = ManualDrive(self.p, self.notes)
        self.calibration = Calibration(self.p, self.notes)

    @property
    def state(self) -> str:
        """Return the state: camera mode's own in camera mode; unheard before the first sample."""
        if self.mode == 'camera':
            return self.cam.state
        if self.mode == 'manual':
            return 'manual' if self.safety.fault == 'none' else 'drive_fault'
        if self.mode == 'calibration':
            return 'calibrating' if self.calibration.running else 'idle'
        if self._wire_time is None and self.mode in ('follow_wire', 'srm'):
            # No pickup sample since start-up: the stream may not have reached this node yet
            # (the world only starting to move), so not lost, but nothing to steer by either.
            return 'unheard'
        return self._state

    @state.setter
    def state(self, value: str) -> None:
        self._state = value  # the guide wire's and the SRM's (camera mode keeps its own)

    @property
    def turn_phase(self) -> str:
        """Return the junction manoeuvre's phase ('' when there is none)."""
        return self.cam.turn.phase

    @property
    def track_guidance(self) -> TrackGuidance:
        """Return the identified track's guidance (its law steers with camera_law feed_forward)."""
        return self.cam.law.track

    @property
    def motor_on(self) -> bool:
        """Return whether camera mode (or manual mode) drives the wheels."""
        return self.manual.motor_on if self.mode == 'manual' else self.cam.motor_on

    @property
    def wheels(self) -> tuple[float, float]:
        """Return the (left, right) rim speeds camera mode (or manual mode) asks for, m/s."""
        return self.manual.wheels if self.mode == 'manual' else self.cam.wheels

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """route_command, guide_wire, wheel_odometry or drive_status."""
        if record == 'route_command':
            return self._command(fields, now)
        if record == 'guide_wire':
            self._wire_time = now
            self._wire(fields['left_coil'], fields['right_coil'], now)
        elif record == 'wheel_odometry':
            self.speed = (fields['left_speed'] + fields['right_speed']) / 2000.0
            self._rim_speeds = (fields['left_speed'] / 1000.0, fields['right_speed'] / 1000.0)
            self.odometry_time = now
            self.cam.odometry(fields)
            self.safety.odometry(fields, self.wheels,
                                 self.motor_on and self.mode in ('camera', 'manual'), now)
        elif record == 'drive_status':
            self.safety.drive_status(fields)
        return None

    def _command(self, fields: dict[str, Any], now: float) -> dict | None:
        # A dead-reckoning leg is one of camera mode's legs, without the camera (App. F.9).
        mode = 'camera' if fields['mode'] == 'dead_reckoning' else fields['mode']
        began = mode == 'camera' and self.cam.command(fields, now, self.mode != 'camera')
        if began or (mode != 'camera' and mode != self.mode):
            self.obstacle.clear()
            self.safety.clear()  # a new leg, or another mode: the software reloaded
        new_srm = mode == 'srm' and fields['manoeuvre'] != self.manoeuvre
        self.manoeuvre = fields['manoeuvre']
        if new_srm:
            self.mode, self.state, self._srm_phase = 'srm', 'srm_running', 'leaving'
            self._srm_start = now
            self.srm_angle = math.radians(fields['srm_angle'])
            # The heading error the manoeuvre starts from: the estimate kept while following.
            self.heading_error = self._following_heading
            return self._outputs(now, force_status=True)
        if mode != 'srm' and mode != self.mode:
            if self.mode == 'camera':
                self.cam.leave()
            self.manual.leave(now)
            self.calibration.stop()
            self.mode, self._integral, self._prev_lateral = mode, 0.0, None
            self.state = {'follow_wire': 'following', 'camera': 'following'}.get(mode, 'idle')
            if mode == 'manual':
                self.manual.enter(now)
            elif mode == 'calibration':  # the camera leading that way (App. F.3)
                self.calibration.begin('rear' if fields['direction'] == 'reverse' else 'front',
                                       now)
            return self._outputs(now, force_status=True)
        return self._outputs(now, force_status=True) if began else None

    # -- guide wire -------------------------------------------------------------------------
    def _wire(self, left: int, right: int, now: float) -> None:
        w, dt = self.p.wire, self.p.period
        # Where the steering actuator is (rate-limited toward the last demand), and how far the
        # truck has turned since the SRM began: psi' = v_rear tan(delta) / wheelbase.
        step = max(-w.steer_rate * dt, min(w.steer_rate * dt, self.steer - self.steer_actual))
        self.steer_actual += step
        self.heading_error += self.speed * math.tan(self.steer_actual) / w.wheelbase * dt
        self.signal = (left + right) / (2.0 * w.nominal)
        present = self.signal >= w.lost_level
        self._weak = 0 if present else self._weak + 1
        self._strong = self._strong + 1 if present else 0
        previous = self.lateral
        self.lateral = wire_offset(left, right, w.coil_spacing, w.coil_height, w.nominal) \
            if present else 0.0
        self._lateral_rate += 0.1 * ((self.lateral - previous) / dt - self._lateral_rate)
        if self.mode == 'follow_wire' and self.speed > 0.1 and present:
            # While following, the front axle stays on the wire, so its path angle
            # psi + delta = -asin(e'/v) gives the heading error; frozen at rest, where the
            # relation does not hold.
            ratio = max(-1.0, min(1.0, self._lateral_rate / self.speed))
            self._following_heading = -self.steer_actual - math.asin(ratio)
        if self.mode == 'follow_wire':
            if self._weak >= w.lost_samples:
                self.state, self.steer = 'lost', 0.0
            elif self.state == 'lost':
                self._rearm()
            elif self.speed < -0.01:
                # Reversing (the slow overshoot correction of Baker 1983, 8.5): with the front
                # wheels trailing the law would steer the wrong way; straight for these few cm.
                self.steer, self._prev_lateral = 0.0, None
            elif self.state != 'lost':
                self._steer_wire()
        elif self.mode == 'srm':
            self._srm(now)

    def _rearm(self) -> None:
        """Leave LOST once the truck is at rest on a wire that is there again.

        A departure from Baker 1983, 7.2 (which stops the truck on a lost wire and says no more): a
        LOST latched for good would also latch on a pickup stream that merely stalls before a task
        (a start-up stall of the graph) and fail the next task with the wire under the truck. It
        comes back only after the LOST record went out (the executive has acted on it), at rest,
        with the wire present for `lost_samples` samples: the law then starts clean.
        """
        at_rest = max(abs(v) for v in self._rim_speeds) < 0.005 and abs(self.speed) < 0.005
        if self._lost_reported and at_rest and self._strong >= self.p.wire.lost_samples:
            self.state = 'following'
            self._integral, self._prev_lateral = 0.0, None

    def _srm(self, now: float) -> None:
        """Leave the wire at the programmed angle; search; capture the next wire."""
        w = self.p.wire
        if self._srm_phase == 'capture':
            if self._weak >= w.lost_samples:
                self.state, self.mode, self.steer = 'lost', 'follow_wire', 0.0
                return
            # Pursuit: aim the front wheels at the wire look_ahead metres on.
            steer = math.atan2(self.lateral, w.look_ahead) - self.heading_error
            self.steer = max(-w.max_steer, min(w.max_steer, steer))
            # Hand over to the PID once near the wire (it removes what heading error is left),
            # or after 5 s of capture within 10 cm.
            aligned = abs(self.lateral) < w.capture_done or (
                now - self._found_at > 5.0 and abs(self.lateral) < 0.10)
            if not aligned:
                self._aligned_since = None
            elif self._aligned_since is None:
                self._aligned_since = now
            elif now - self._aligned_since > 0.3:
                self.mode, self.state = 'follow_wire', 'following'
                self._integral, self._prev_lateral = 0.0, None
            return
        self.steer = max(-w.max_steer, min(w.max_steer, self.srm_angle))
        if self._srm_phase == 'leaving' and self.signal < w.lost_level:
            self._srm_phase = 'searching'
        elif self._srm_phase == 'searching' and self.signal >= w.found_level:
            self._srm_phase, self.state, self._found_at = 'capture', 'wire_found', now
            self._aligned_since = None
        elif now - self._srm_start > w.srm_timeout:
            self.state, self.mode, self.steer = 'lost', 'follow_wire', 0.0

    def _steer_wire(self) -> None:
        w, dt = self.p.wire, self.p.period
        rate = 0.0 if self._prev_lateral is None else (self.lateral - self._prev_lateral) / dt
        self._prev_lateral = self.lateral
        if abs(self.speed) >= w.hold_integral_below:
            self._integral = max(-0.2, min(0.2, self._integral + self.lateral * dt))
        steer = w.kp * self.lateral + w.ki * self._integral + w.kd * rate
        self.steer = max(-w.max_steer, min(w.max_steer, steer))

    # -- camera ---------------------------------------------------------------------------
    def on_sonar(self, reading: float, now: float) -> dict | None:
        """Take a front sonar reading (m; +inf no echo, -inf too near to time)."""
        self.obstacle.reading(reading, now)
        return None  # a stop goes out with the loop's steering_command

    @property
    def drive_fault(self) -> str:
        """Return the fault camera mode stops on: the supervisor's, or a silent sonar."""
        fault = self.safety.fault
        return 'sonar_silent' if fault == 'none' and self.obstacle.holding \
            and self.obstacle.silent else fault

    def health(self) -> tuple[int, str]:
        """Return the sonar's verdict for /diagnostics (the camera truck's)."""
        return self.obstacle.health() if self.p.vehicle == 'concic2' else (0, '')

    def on_frame(self, frame: np.ndarray, now: float, camera: str = 'front') -> dict | None:
        """Take a binary frame (1 = dark tape) from the front or the rear camera."""
        if self.mode == 'camera':
            self.cam.frame(frame, now, camera)
        elif self.mode == 'calibration':
            self.calibration.frame(frame, now, camera)
        return None  # the wheel speeds go out with the loop's steering_command

    def on_twist(self, linear: tuple[float, float, float], angular: tuple[float, float, float],
                 now: float) -> str:
        """Take a cmd_vel Twist; return 'taken' or why it was refused (manual_drive.REFUSALS)."""
        return self.manual.command(linear, angular, now, self.safety.fault)

    # -- outputs ----------------------------------------------------------------------------
    def tick(self, now: float) -> dict | None:
        """Steering command every period; status on change and as a heartbeat."""
        w = self.p.wire
        last = self._wire_time  # None: never heard, which the state says (unheard), not lost
        if self.mode in ('follow_wire', 'srm') and last is not None \
                and now - last > w.lost_samples * 0.01 + 0.05:
            self.state, self.steer = 'lost', 0.0  # the pickup itself has gone quiet
        if self.state == 'wire_found' and self.mode == 'follow_wire':
            self.state = 'following'
        self.obstacle.check(now)
        if self.mode == 'camera':
            self.cam.tick(now)
        return self._outputs(now)

    def _outputs(self, now: float, force_status: bool = False) -> dict:
        if self.mode == 'camera' and self.drive_fault != 'none':
            self.cam.drive_fault(now)
        if self.mode == 'camera':  # the sonar holds the wheels at rest while it sees one
            self.cam.hold(self.obstacle.holding)
        self.manual.tick(now, self.safety.fault)  # the watchdog, and a fault stops it at once
        out: dict[str, dict[str, Any]] = {'steering_command': self.steering_command()}
        state = self.cam.reported_state() if self.mode == 'camera' else self.state
        if force_status or now >= self._next_status or state != self._last_state:
            self._next_status, self._last_state = now + self.p.status_period, state
            self._lost_reported = self.state == 'lost'
            out['route_status'] = self.status()
        return out

    def steering_command(self) -> dict[str, Any]:
        """Return the steering_command record for the configured vehicle."""
        if self.p.vehicle == 'concic2':
            # Within the DAC's full-speed level, or the safety PAL trips on over-voltage
            # (Rajagopalan 1991, 6.3.11); each wheel on its own, as the drive's limit did before.
            top = self.p.drive_safety.full_speed
            left, right = (max(-top, min(top, v)) for v in self.wheels)
            driving = self.motor_on and self.mode in ('camera', 'manual')
            return {'mode': 'wheel_speeds', 'enable': int(driving),
                    'angle': 0, 'left_speed': int(round(left * 1000)),
                    'right_speed': int(round(right * 1000))}
        active = self.mode in ('follow_wire', 'srm') and self.state not in ('lost', 'unheard')
        angle = int(round(max(-1.0, min(1.0, self.steer)) * 1000))
        return {'mode': 'angle', 'enable': 1, 'angle': angle if active else 0,
                'left_speed': 0, 'right_speed': 0}

    def status(self) -> dict[str, Any]:
        """Return the route_status record."""
        if self.mode == 'camera':
            return {**self.cam.status(), 'manoeuvre': self.manoeuvre,
                    'drive_fault': self.drive_fault}
        if self.mode == 'calibration' and (result := self.calibration.result) and result.normal:
            # App. F.3's display: the track's position (mm) and orientation (deg) measured
            self.lateral, self.steer = result.eps_d, result.eps_theta
            self.signal = result.normal / result.frames
        return {
            'state': self.state,
            'lateral_error': int(max(-128, min(127, round(self.lateral * 1000)))),
            'signal': int(max(0, min(255, round(self.signal * 100)))),
            'steering': int(max(-128, min(127, round(math.degrees(self.steer))))),
            'sign_left': 0, 'sign_right': 0, 'sign_straight': 0, 'manoeuvre': self.manoeuvre,
            **self.cam.leg_fields(), 'drive_fault': self.drive_fault,
        }
