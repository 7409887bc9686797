"""Vehicle dynamics: the A.W.D. Electruk tug (Baker 1983) and CONCIC-II (Rajagopalan 1991).

Electruk (Baker 1983, 6.3.2): rear drive by two 0.4 kW separately excited d.c. motors in parallel
from 24 V through a one-quadrant PWM chopper (armature duty 0-80 %), a PWM field supply whose
direction the traction board flips, reduction gearing and chains to the rear wheels, Ackermann
front steering by an actuator with rate and angle limits. Per motor:

    L di/dt = duty * V_batt - R i - k_phi(field) * w_m ,  i >= 0 (chopper + freewheel diode)
    torque = k_phi(field) * i

so reversing the field while the truck still rolls forward makes the back-EMF add to the supply and
the torque oppose the motion: plug braking (Baker 1983, 6.3, 8.5), limited by the controller's
current limit. With the armature off only friction acts (the "friction only" braking of the 1983
stop). Parameters marked [A] are assumptions (agv_nodes.world.settings.ElectrukParams).

CONCIC-II (Rajagopalan 1991: the vehicle 6.3.1-6.3.2, Table 6.1, App. B.3-B.5, App. C; the
kinematics 3.5; the LM628 and the coast 7.3.2, 7.3.4): differential drive, wheel radius 0.075 m,
casters; each wheel's commanded speed is approached at a fixed acceleration (the LM628 trapezoid)
and followed with a first-order lag; "motor off" coasts down (5 mm from 0.16 m/s).
"""

from dataclasses import dataclass
import math
from types import ModuleType

from agv_nodes.world import kernels
from agv_nodes.world.settings import Concic2Params, ElectrukParams

G = 9.81


@dataclass
class VehicleState:
    """Pose of the vehicle reference point (rear axle centre / drive axle centre)."""

    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    speed: float = 0.0  # m/s along the heading
    yaw_rate: float = 0.0
    distance: float = 0.0  # odometer, m (signed travel summed)


def advance_pose(s: VehicleState, v: float, yaw_rate: float, dt: float) -> None:
    """Move the pose by one step at speed `v` and `yaw_rate` (midpoint heading)."""
    s.yaw_rate = yaw_rate
    h_mid = s.heading + 0.5 * yaw_rate * dt
    s.x += v * math.cos(h_mid) * dt
    s.y += v * math.sin(h_mid) * dt
    s.heading += yaw_rate * dt
    s.distance += v * dt


class Electruk:
    """The tug: DC drive + Ackermann kinematics (bicycle model about the rear axle)."""

    kind = 'electruk'

    def __init__(self, params: ElectrukParams,
                 compiled: ModuleType | None = kernels.compiled) -> None:
        """`compiled`: the C kernels that step it (agv_nodes.world.kernels), or None: Python."""
        self.p = params
        # the kernel itself, not its module: a world is deep-copied (forked test states)
        self._step_kernel = compiled.electruk_step if compiled is not None else None
        self.state = VehicleState()
        self.steer = 0.0  # front wheel angle, rad
        self.current = 0.0  # armature current per motor, A
        self.flux = 1.0  # field flux as a fraction of full field, signed (+ = forward)
        # Inputs (held between updates, as the hardware holds its PWM registers).
        self.armature_duty = self.field_duty = 0.0  # 0..0.8, 0..1
        self.field_forward = True
        self.armature_enable = self.field_enable = self.contactor = False
        self.relay_closed = True  # the trip relay, held closed by the watchdog monostable
        self.radio_stop = self.steer_enable = False
        self.steer_demand = 0.0
        self._step_key: tuple[float, ...] | None = None
        self._step_constants: tuple[float, ...] = ()

    @property
    def mass(self) -> float:
        """Total mass, kg."""
        return self.p.mass + self.p.payload

    @property
    def sensor_point(self) -> tuple[float, float]:
        """The front axle centre: guide-wire coils and marker sensor are in line with it."""
        s = self.state
        return (s.x + self.p.wheelbase * math.cos(s.heading),
                s.y + self.p.wheelbase * math.sin(s.heading))

    def set_drive(self, armature_duty: float, field_duty: float, field_forward: bool,
                  armature_enable: bool, field_enable: bool, contactor: bool) -> None:
        """Latch the traction_drive outputs."""
        self.armature_duty, self.field_duty, self.field_forward = (armature_duty, field_duty,
                                                                   field_forward)
        self.armature_enable, self.field_enable, self.contactor = (armature_enable, field_enable,
                                                                   contactor)

    @property
    def pushing(self) -> bool:
        """The drive is pushing the truck along its motion (ground truth for `drive_off`)."""
        powered = self.contactor and self.relay_closed and not self.radio_stop
        forward = self.state.speed >= 0.0
        return (powered and self.armature_enable and self.armature_duty > 0.0
                and self.field_enable and self.field_forward == forward)

    def _constants(self, dt: float) -> tuple[float, ...]:
        """Return what step() needs that only dt, the parameters and the load set (cached)."""
        p = self.p
        key = (dt, id(p), p.mass, p.payload)
        if self._step_key != key:
            self._step_key = key
            self._step_constants = (
                1.0 - math.exp(-dt / p.field_time_constant),
                math.exp(-dt * p.armature_resistance / p.armature_inductance),
                self.mass * p.inertia_factor,
                p.motors * p.drivetrain_friction * p.gear_ratio / p.wheel_radius
                + p.rolling_resistance * self.mass * G,
                p.motors * p.viscous_friction * (p.gear_ratio / p.wheel_radius) ** 2,
                p.battery_voltage, p.wheel_radius, p.gear_ratio, p.k_phi,
                p.armature_resistance, p.current_limit, p.wheelbase, p.motors * p.k_phi)
        return self._step_constants

    def step(self, dt: float, n: int = 1) -> None:
        """Advance by `n` steps of dt seconds (the world's substeps of a sample in one call)."""
        p, s = self.p, self.state
        (field_gain, decay, m_eff, coulomb, viscous_per_speed, battery_voltage, radius, gear,
         k_phi, resistance, limit, wheelbase, motors_k_phi) = self._constants(dt)
        # The inputs hold over the n steps: what depends only on them is worked out once, and
        # the state is carried in locals (the arithmetic and its order are those of one step).
        powered = self.contactor and self.relay_closed and not self.radio_stop
        # Field: first-order toward duty x direction; with the contactor open it decays too.
        target = (self.field_duty * (1 if self.field_forward else -1)
                  if powered and self.field_enable else 0.0)
        driven = powered and self.armature_enable
        v_arm = self.armature_duty * battery_voltage
        steering = self.steer_enable
        if steering:
            demand, most = self.steer_demand, p.max_steer
            if demand < -most:
                demand = -most
            if demand > most:
                demand = most
            rate = p.steer_rate * dt
        if self._step_kernel is not None:  # the same arithmetic in C (world.kernels)
            (self.flux, self.current, self.steer, s.x, s.y, s.heading, s.distance, s.speed,
             s.yaw_rate) = self._step_kernel(
                n, dt, field_gain, decay, m_eff, coulomb, viscous_per_speed, target, driven,
                v_arm, radius, gear, k_phi, resistance, limit, wheelbase, motors_k_phi,
                steering, demand if steering else 0.0, rate if steering else 0.0, self.flux,
                self.current, self.steer, s.x, s.y, s.heading, s.distance, s.speed, s.yaw_rate)
            return
        copysign, tan, cos, sin = math.copysign, math.tan, math.cos, math.sin
        flux, current, steer = self.flux, self.current, self.steer
        tan_of, tan_steer = steer, tan(steer)  # tan of the steer angle, redone when it moves
        x, y, heading, distance, v = s.x, s.y, s.heading, s.distance, s.speed
        yaw = s.yaw_rate
        for _ in range(n):
            flux += (target - flux) * field_gain
            back_emf = k_phi * flux * (v / radius * gear)
            if driven:
                i_ss = (v_arm - back_emf) / resistance
                current = i_ss + (current - i_ss) * decay
            else:  # chopper off: the current freewheels away through the diode
                current *= decay
            if current < 0.0:
                current = 0.0
            if current > limit:
                current = limit
            if current < 1e-6:
                current = 0.0
            # torque at the motor shafts, then the force at the wheels
            drive_force = motors_k_phi * flux * current * gear / radius
            # Friction: Coulomb drivetrain + rolling resistance + viscous, opposing motion; at
            # rest it holds the truck unless the drive force exceeds it (stiction = same level).
            held = -coulomb <= drive_force <= coulomb
            if v == 0.0 and held:
                v_new = 0.0  # stiction holds it
            else:
                direction = copysign(1.0, v if v != 0.0 else drive_force)
                v_new = v + (drive_force - direction * coulomb - viscous_per_speed * v) \
                    / m_eff * dt
                if v != 0.0 and held and copysign(1.0, v_new) != direction:
                    v_new = 0.0  # friction brings it to rest; it does not reverse it
            # Steering actuator: rate- and angle-limited toward the demand.
            if steering:
                delta = demand - steer
                if delta < -rate:
                    delta = -rate
                if delta > rate:
                    delta = rate
                steer += delta
                if steer != tan_of or steer == 0.0:  # (a zero's sign matters to tan)
                    tan_of, tan_steer = steer, tan(steer)
            # advance_pose, inline: midpoint heading
            v_mid = 0.5 * (v + v_new)
            yaw = v_mid * tan_steer / wheelbase
            h_mid = heading + 0.5 * yaw * dt
            x += v_mid * cos(h_mid) * dt
            y += v_mid * sin(h_mid) * dt
            heading += yaw * dt
            distance += v_mid * dt
            v = v_new
        self.flux, self.current, self.steer = flux, current, steer
        s.x, s.y, s.heading, s.distance, s.speed, s.yaw_rate = x, y, heading, distance, v, yaw

    def wheel_speeds(self) -> tuple[float, float]:
        """Rear (driven) wheel rim speeds, left and right, m/s."""
        w = self.state.yaw_rate * self.p.track / 2.0
        return self.state.speed - w, self.state.speed + w


class Concic2:
    """CONCIC-II: differential drive about the drive-axle centre O, commanded wheel speeds."""

    kind = 'concic2'

    def __init__(self, params: Concic2Params) -> None:
        self.p = params
        self.state = VehicleState()
        self.left = self.right = 0.0  # actual wheel rim speeds, m/s
        self.left_profile = self.right_profile = 0.0  # LM628 trajectory generator outputs
        self.left_demand = self.right_demand = 0.0
        self.enable = self.radio_stop = False

    @property
    def sensor_point(self) -> tuple[float, float]:
        """The front camera window centre."""
        s = self.state
        return (s.x + self.p.camera_distance * math.cos(s.heading),
                s.y + self.p.camera_distance * math.sin(s.heading))

    @property
    def pushing(self) -> bool:
        """The LM628s drive the wheels (ground truth for `drive_off`: motor off or radio stop)."""
        return self.enable and not self.radio_stop

    def set_wheels(self, left: float, right: float, enable: bool) -> None:
        """Latch the wheel speed demands (m/s)."""
        lim = self.p.max_wheel_speed
        self.left_demand = min(max(left, -lim), lim)
        self.right_demand = min(max(right, -lim), lim)
        self.enable = enable

    def step(self, dt: float) -> None:
        """Advance by dt seconds."""
        p, s = self.p, self.state
        if self.enable and not self.radio_stop:
            a = p.acceleration * dt
            self.left_profile += min(max(self.left_demand - self.left_profile, -a), a)
            self.right_profile += min(max(self.right_demand - self.right_profile, -a), a)
            k = 1.0 - math.exp(-dt / p.lag)
            self.left += (self.left_profile - self.left) * k
            self.right += (self.right_profile - self.right) * k
        else:  # motor off: no feedback, the wheels coast down together
            v = 0.5 * (self.left + self.right)
            dv = p.coast_deceleration * dt
            scale = max(abs(v) - dv, 0.0) / abs(v) if v != 0.0 else 0.0
            self.left, self.right = self.left * scale, self.right * scale
            self.left_profile, self.right_profile = self.left, self.right
        v = 0.5 * (self.left + self.right)
        advance_pose(s, v, (self.right - self.left) / p.wheel_span, dt)
        s.speed = v

    def wheel_speeds(self) -> tuple[float, float]:
        """Wheel rim speeds, left and right, m/s."""
        return self.left, self.right
