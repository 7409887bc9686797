"""Route following: guide-wire steering, software-resident manoeuvres, binary-camera guidance.

Guide wire (Baker 1983, 3.5.3, 6.2.1, 7.2): the coil amplitudes give the wire's lateral offset from
the sensor point (`wire_offset`), and a PI law with a derivative term for damping steers the
Ackermann front wheels. A signal below `lost_level` for `lost_samples` samples, or no pickup sample
for that long, reports LOST at once (the executive stops the truck) until the truck is at rest with
the wire present again. An SRM (mode srm, a new `manoeuvre`) leaves the wire at the programmed
steering angle until the signal drops and a wire is found again, then follows it (7.2 task 7).

Camera (Rajagopalan 1991, mode camera, the differential-drive CONCIC-II): each frame is analysed
(agv_nodes.route_following.camera_guidance), the P or PI law gives the caster angle, and Eq
5.15/5.16 the wheel speeds. Four absent frames stop the vehicle (motor off); a saturated frame
keeps the last command. At a road sign the junction choice of route_command is taken (App. F.6):
once the chosen branch shows at the window's edge column the vehicle stops with its axle centre
over the crossing (by wheel odometry), spins a quarter turn toward the branch and follows it. A
chosen branch the sign does not offer stops it ("no_branch": "the vehicle stops with a message"); a
straight choice where the track ends stops it by the four absent frames.
"""

import math
from typing import Any

import numpy as np

from agv_nodes.odometry import Odometer
from agv_nodes.route_following.camera_guidance import CameraSteering, ImageAnalyser, Validity
from agv_nodes.route_following.settings import RouteParams
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
    pairs = [(a, b) for a in (c - y_left, c + y_left) for b in (-c + y_right, -c - y_right)]
    a, b = min(pairs, key=lambda ab: abs(ab[0] - ab[1]))
    return 0.5 * (a + b)


class RouteCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'route_following', RouteParams, 'period'

    def __init__(self, params: RouteParams | None = None) -> None:
        super().__init__(params)
        self.mode = self.state = 'idle'
        self.manoeuvre, self.junction = 0, 'straight'
        self.srm_angle = self.speed_request = self.lateral = self.signal = self.steer = 0.0
        self._integral = self._srm_start = self._mode_since = 0.0
        self._prev_lateral: float | None = None
        self._weak = 0
        self._strong = 0  # consecutive samples with the wire present
        self._lost_reported = False  # a route_status with state lost has gone out
        self._srm_phase = ''
        self._found_at = -1e9
        self._wire_time: float | None = None
        self.speed = 0.0  # m/s from wheel odometry
        self.steer_actual = 0.0  # model of the actuator's position
        self.heading_error = 0.0  # SRM: heading relative to the wire left (new wire parallel)
        self._aligned_since: float | None = None
        self._lateral_rate = 0.0  # filtered d(lateral)/dt, m/s
        self._following_heading = 0.0  # heading error relative to the wire, while following
        self._next_status, self._last_state = 0.0, ''
        # camera
        self.analyser = ImageAnalyser(self.p.image)
        self.camera = CameraSteering(self.p.steering)
        self.wheels = (0.0, 0.0)
        self.motor_on = self._in_sign = False
        self.sign = {'left': 0, 'right': 0, 'straight': 0}
        self._frame_time: float | None = None
        self.measurement = None
        self.turn_phase = ''  # '' | 'approach' (to the crossing) | 'spin' | 'settle' (to rest)
        self._rim_speeds = (0.0, 0.0)  # m/s, from wheel odometry
        self._wheels = Odometer()  # each wheel's travel, from the encoders' counters
        self._turn_from = (0.0, 0.0)  # each wheel's travel when the phase began, m
        self._turn_way = 0  # +1 left, -1 right
        self._crossing = 0.0  # m of axle travel from the sighting to the crossing
        self._turn_began: float | None = None  # sim time the manoeuvre's first pass ran
        self._set_off_at: float | None = None  # sim time the vehicle set off from rest

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """route_command, guide_wire or wheel_odometry."""
        if record == 'route_command':
            return self._command(fields, now)
        if record == 'guide_wire':
            self._wire_time = now
            self._wire(fields['left_coil'], fields['right_coil'], now)
        elif record == 'wheel_odometry':
            self.speed = (fields['left_speed'] + fields['right_speed']) / 2000.0
            self._rim_speeds = (fields['left_speed'] / 1000.0, fields['right_speed'] / 1000.0)
            self._wheels.update(fields['left_distance'], fields['right_distance'])
        return None

    def _command(self, fields: dict[str, Any], now: float) -> dict | None:
        self.junction = fields['junction']
        mode = fields['mode']
        new_srm = mode == 'srm' and fields['manoeuvre'] != self.manoeuvre
        self.manoeuvre = fields['manoeuvre']
        if new_srm:
            self.mode, self.state, self._srm_phase = 'srm', 'srm_running', 'leaving'
            self._mode_since = self._srm_start = now
            self.srm_angle = math.radians(fields['srm_angle'])
            # The heading error the manoeuvre starts from: the estimate kept while following.
            self.heading_error = self._following_heading
            return self._outputs(now, force_status=True)
        if mode != 'srm' and mode != self.mode:
            self.mode, self._mode_since, self._integral, self._prev_lateral = mode, now, 0.0, None
            self.state = {'idle': 'idle', 'follow_wire': 'following', 'camera': 'following'}[mode]
            return self._outputs(now, force_status=True)
        return None

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
        self._integral = max(-0.2, min(0.2, self._integral + self.lateral * dt))
        steer = w.kp * self.lateral + w.ki * self._integral + w.kd * rate
        self.steer = max(-w.max_steer, min(w.max_steer, steer))

    # -- camera -----------------------------------------------------------------------------
    def on_frame(self, frame: np.ndarray, now: float) -> dict | None:
        """Take a binary camera frame (1 = dark tape)."""
        dt = 0.05 if self._frame_time is None else max(now - self._frame_time, 1e-3)
        self._frame_time = now
        m = self.measurement = self.analyser.analyse(frame)
        self._road_sign(m)
        if self.mode != 'camera' or self.state == 'no_branch':
            return None
        if self.turn_phase in ('spin', 'settle'):
            return None  # the window sweeps the floor: nothing to steer by until the turn ends
        if not self.turn_phase and self._in_sign and self.junction != 'straight' \
                and (m.left_edge if self.junction == 'left' else m.right_edge):
            self._start_turn('approach')  # the chosen branch is in sight
            t = self.p.turning
            self._crossing = t.camera_ahead + t.detect_lead
        if self.turn_phase == 'approach' and self.p.turning.crossing_from == 'image':
            edge = self.analyser.branch_edge(frame, self.junction)
            if edge is not None:  # the crossing, measured from where the axle is now
                half = self.analyser.normal_width * self.analyser.mm_col / 2.0
                self._crossing = self._turned()[0] + self.p.turning.camera_ahead + edge + half
        theta = self.camera.update(m, dt, self.speed_request or self.p.camera_speed)
        if theta is None:
            # four absent frames: motor-off stop
            self.motor_on, self.state, self.wheels = False, 'lost', (0.0, 0.0)
        else:
            self.motor_on = self.state != 'lost'
            self.steer = theta
            if m.validity is not Validity.ABSENT:
                self.lateral = m.eps_d
            if self.turn_phase == 'approach':
                return None  # _turn drives to the crossing with this steering angle
            speed = self.speed_request or self.p.camera_speed
            if self._set_off_at is None and abs(self.speed) < 0.01 \
                    and self.p.steering.set_off_acceleration > 0:
                self._set_off_at = now
            if self._set_off_at is not None:
                # Setting off from rest: our own ramp, gentler than the drive's trapezoid, which
                # accelerates both wheels alike and cannot steer while it ramps (from 40 deg
                # off the tape the window loses it before the wheels reach cruise).
                speed = min(speed, self.p.steering.set_off_acceleration * (now - self._set_off_at))
                if speed >= (self.speed_request or self.p.camera_speed):
                    self._set_off_at = None
            self.wheels = self.camera.wheel_speeds(speed, theta) if self.motor_on else (0, 0)
        return None

    # -- junctions (Rajagopalan 1991, App. F.6) ---------------------------------------------
    def _start_turn(self, phase: str) -> None:
        self.turn_phase = phase
        self._turn_from = (self._wheels.left, self._wheels.right)
        self._turn_way = 1 if self.junction == 'left' else -1
        self.state = 'turning'

    def _turned(self) -> tuple[float, float]:
        """(m the axle centre has moved, rad the vehicle has turned) since the phase began."""
        left = self._wheels.left - self._turn_from[0]
        right = self._wheels.right - self._turn_from[1]
        return (left + right) / 2.0, (right - left) / self.p.steering.wheel_span

    def _to_crossing(self) -> float:
        """M the axle centre still has to go to be over the crossing (< 0: past it)."""
        return self._crossing - self._turned()[0]

    def _profile(self, distance: float, top: float) -> float:
        """Speed that comes to rest in `distance` at the turning's deceleration."""
        return min(top, math.sqrt(2.0 * self.p.turning.stop_deceleration * max(distance, 0.0)))

    def _turn(self, now: float) -> None:
        """Approach, spin, settle: at the loop rate (the frames come at only ~20 Hz)."""
        t = self.p.turning
        if self._turn_began is None:
            self._turn_began = now
        if now - self._turn_began > t.turn_timeout:
            # Odometry that stopped counting (or a wheel that will not turn) must not leave
            # the vehicle spinning or creeping: motors off, as for a lost tape.
            self.turn_phase, self._turn_began = '', None
            self.state, self.motor_on, self.wheels = 'lost', False, (0.0, 0.0)
            return
        if self.turn_phase == 'approach':
            remaining = self._to_crossing()
            if abs(remaining) > t.position_tolerance or abs(self.speed) > 0.01:
                if remaining >= 0:  # steered by the tape, slowing to a stop over the crossing
                    speed = self._profile(remaining, min(t.approach_speed, self.p.camera_speed))
                    self.wheels = self.camera.wheel_speeds(speed, self.steer)
                else:  # braked past it (from a high cruise): straight back onto it
                    speed = self._profile(-remaining, t.approach_speed)
                    self.wheels = (-speed, -speed)
                self.motor_on = True
                return
            self._start_turn('spin')
        if self.turn_phase == 'spin':
            # A wheel speed profile that ends the quarter turn at rest (the drive's trapezoid
            # brakes at 0.3 m/s^2: cut short at full speed it would overshoot by ~8 deg), and
            # turns back what the wheels' lag carried it past.
            error = math.radians(t.spin_angle) - self._turn_way * self._turned()[1]
            arc = error * self.p.steering.wheel_span / 2.0
            w = math.copysign(self._profile(abs(arc), t.spin_speed), arc)
            if abs(error) > math.radians(t.angle_tolerance) or \
                    max(abs(v) for v in self._rim_speeds) > 0.005:
                w *= self._turn_way
                self.wheels, self.motor_on = (-w, w), True
                return
            self.turn_phase, self.wheels = 'settle', (0.0, 0.0)
        if max(abs(v) for v in self._rim_speeds) > 0.005:
            return  # still turning
        # On the branch: follow it afresh (the fit takes the widest run, the law starts clean).
        self.turn_phase, self._turn_began, self._set_off_at = '', None, now
        self.camera.integral = 0.0
        self.analyser.forget_track()
        self._in_sign, self.state = False, 'following'

    def _road_sign(self, m) -> None:
        """Branch flags while the track is wide (Rajagopalan 1991, 4.3)."""
        if m.validity is Validity.WIDE:
            if not self._in_sign:
                self._in_sign = True
                self.sign = {'left': 0, 'right': 0, 'straight': 0}
            self.sign['left'] |= int(m.left_edge)
            self.sign['right'] |= int(m.right_edge)
        elif self._in_sign and m.validity is Validity.NORMAL:
            self._in_sign = False
            if self.sign['left'] or self.sign['right']:
                self.sign['straight'] = 1  # width back to normal after a turn signal
            if self.mode == 'camera' and self.junction != 'straight' and not self.turn_phase:
                # The sign is behind us and its branches did not include the one chosen.
                self.state, self.motor_on, self.wheels = 'no_branch', False, (0.0, 0.0)

    # -- outputs ----------------------------------------------------------------------------
    def tick(self, now: float) -> dict | None:
        """Steering command every period; status on change and as a heartbeat."""
        w = self.p.wire
        last = self._wire_time if self._wire_time is not None else self._mode_since
        if self.mode in ('follow_wire', 'srm') and now - last > w.lost_samples * 0.01 + 0.05:
            self.state, self.steer = 'lost', 0.0  # the pickup itself has gone quiet
        if self.state == 'wire_found' and self.mode == 'follow_wire':
            self.state = 'following'
        if self.turn_phase and self.mode == 'camera':
            self._turn(now)
        return self._outputs(now)

    def _outputs(self, now: float, force_status: bool = False) -> dict:
        out: dict[str, dict[str, Any]] = {'steering_command': self.steering_command()}
        if force_status or now >= self._next_status or self.state != self._last_state:
            self._next_status, self._last_state = now + self.p.status_period, self.state
            self._lost_reported = self.state == 'lost'
            out['route_status'] = self.status()
        return out

    def steering_command(self) -> dict[str, Any]:
        """Return the steering_command record for the configured vehicle."""
        if self.p.vehicle == 'concic2':
            left, right = self.wheels
            return {'mode': 'wheel_speeds', 'enable': int(self.motor_on and self.mode == 'camera'),
                    'angle': 0, 'left_speed': int(round(left * 1000)),
                    'right_speed': int(round(right * 1000))}
        active = self.mode in ('follow_wire', 'srm') and self.state != 'lost'
        angle = int(round(max(-1.0, min(1.0, self.steer)) * 1000))
        return {'mode': 'angle', 'enable': 1, 'angle': angle if active else 0,
                'left_speed': 0, 'right_speed': 0}

    def status(self) -> dict[str, Any]:
        """Return the route_status record."""
        sign_state = self._in_sign and self.mode == 'camera' and not self.turn_phase
        return {
            'state': 'sign' if sign_state else self.state,
            'lateral_error': int(max(-128, min(127, round(self.lateral * 1000)))),
            'signal': int(max(0, min(255, round(self.signal * 100)))),
            'steering': int(max(-128, min(127, round(math.degrees(self.steer))))),
            'sign_left': self.sign['left'], 'sign_right': self.sign['right'],
            'sign_straight': self.sign['straight'], 'manoeuvre': self.manoeuvre,
        }
