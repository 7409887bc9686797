"""CONCIC-II as Huang's dynamic model driven by two LM628 servo loops (Rajagopalan 1991, App. G).

Body (App. G.4-G.5, Eq. G.53 with the J the printed yaw equation drops): the truck with both
drive wheels is one rigid body with two degrees of freedom, forward speed V and yaw rate W about
the drive-axle centre O (mass centre at O, no slip, load shared equally, N = W/4 per wheel,
Eq. G.1). In wheel rim speeds v1 (left), v2 (right), V = (v1 + v2)/2, W = (v2 - v1)/(2l):

    (m + 2 n^2 J / r^2) dV/dt         = (n/r)(T1 + T2) - rolling - casters
    (I_z + 2 n^2 l^2 J / r^2) dW/dt   = l (n/r)(T2 - T1) + l (F1f - F2f) + x_p F_caster,y

with per-motor shaft torque T = K_t i - b w - T_f sign(w) (Eq. G.32-G.35), rolling resistance
k1 (1 + k2 |v|) N at each wheel (Eq. G.44-G.46, k1 0.007, k2 0.01). Coulomb terms (T_f and
rolling) are applied as bounded impulses, so the wheels stop and stick instead of reversing.

Casters (Eq. G.19-G.25, G.52, Eq. 5.10-5.11): negligible mass and a frictionless pivot, so the
contact rolls along the caster heading and the caster swivels by the no-side-slip law
d(delta)/dt = (|v_p|/s) sin(alpha - delta) - W (alpha: direction of the pivot velocity); it
passes to the body its rolling resistance and Huang's side friction k_n N sign(alpha - delta),
k_n 0.01. Pivots at x = L_a + s (front) and -(L_a - s) (rear) [D]: L_a is the axle-to-contact
distance at zero caster angle (Eq. 5.11), the front contact trailing its pivot by s.

Drive (App. B.4-B.5, 7.2): K_t 0.114 N m/A, R_a 0.602 ohm, L_a 4.7 mH, J_m 0.002 kg m^2,
gear 9.9, r 0.075 m. Departures, each [D]:

- K_e = K_t = 0.114 V s/rad (SI identity of a PM motor). The thesis's 0.163 (Eq. B.8) is a
  ratio of two curve slopes; with it the motor could reach neither its 1700 rpm no-load speed
  (Eq. B.11) nor its 0.088 s mechanical time constant (Eq. B.14) at 24 V.
- The damping D = 0.0228 N m s of Eq. B.13 is the constant-voltage slope stall torque / no-load
  speed; K_t K_e / R_a supplies 0.0216 of it, the rest is viscous friction b = 0.0012, so that
  tau_m = J_m / D = 0.088 s with the armature in circuit.
- Coulomb friction T_f = K_t 24 V / R_a - D w_nl = 0.486 N m, so the free motor turns 1700 rpm
  at 24 V. The printed static friction, 8.2 N m (Eq. B.10), exceeds the stall torque.

Amplifier (6.3.3, App. C.2, 7.2): Galil ESA 15/75H in current mode with the armature-voltage
feedback that C.2.3.5 calls "actually a velocity feedback loop", its gain set "until the motor
response is critically damped" (5 % overshoot) with the LM628 closing the position loop. [D]
Modelled as that speed loop: the current asked for is G_in V_in - G_v w (w the motor speed, the
back-EMF the feedback measures), followed behind the 1 ms lag of the current amplifier (Eq.
C.2), limited to 36 A peak, 9 A continuous after 0.39 s above it (C.2.3.1), and no faster than
24 V can drive the armature. G_in holds max_wheel_speed at 4.2 V in, the full speed of 7.2.1
and 6.3.11. DAC 0.09 V per code [D] (4.2 V over the ~47 codes each side of mid-scale that
7.2.1 measured), input limited to +-7 V (C.1.7.3). Motor off (enable false): the LM628 puts
out zero ("a zero voltage is given as an output to the motors", 7.3.4), the speed loop brakes
the wheels to rest. Radio stop (E-stop): the relays open the armature (6.3.11): no current,
friction only.

Why a speed loop and G_v = 2.0 A s/rad [D]. A terminal-voltage source (V_t = 24/4.2 V_in)
damps a wheel only by its shorted back-EMF, K_t K_e / R_a: 376 N s/m at the rim against the
263 kg each wheel carries of the loaded truck's yaw (the yaw mode is 1.7 times heavier than the
straight-line one). Under the thesis's LM628 gains that position loop had about 0.1 of critical
damping: a 0.03 m/s differential step overshot the yaw rate by 79 % and rang at 1.2 Hz, and the
camera laws locked into that ring (front and rear windows swinging +-75 mm in anti-phase,
period 0.8 s). No gain of an armature-voltage feedback without its IR drop removed damps
beyond that short, so C.2.3.5's critical damping needs the back-EMF itself fed back. G_v fits
three things the thesis measured on the truck: a differential step overshoots 7 % (C.2.3.5:
5 %), a wheel trails its ramp by 0.16 s (6.3.8: the servo loop's time constant is four 44 ms
vision cycles, 0.18 s), and motor off stops the truck in 5.3 mm from 0.16 m/s (7.3.4, Fig.
7.9: 5 mm), where a voltage source coasted 20 mm. G_v 1.5 stops in 6.0 mm, 2.5 in 4.6 mm; the
speed step from rest overshoots 1 % (7.5.2.1: 1 %).

The servo loop's time constant [D], measured (bench/concic2_thesis_bench.py, the drive table):
a differential step with the trapezoid's acceleration at 30 m/s^2, so that the profile is a
step, reaches 63 % of its yaw rate in 0.198 s; through the 0.3 m/s^2 trapezoid, 0.242 s. The
thesis bounds it by its cycle: "the cycle time is one quarter of the time constant of the servo
loop" (6.3.8), the cycle 40-60 ms (6.3.10, 7.5.1.6): 0.16-0.24 s. G_v and the output shift
(lm628) set it; the fits above pin G_v, and shifts 15 and 17 give 0.108 and 0.302 s.

Yaw inertia [D]: Table B.1 masses, the two batteries (120 lb) as points at their App. B.3
centres, the other 153.5 lb as a uniform 1115 x 781 mm plate: 22.2 kg m^2; payload [A] a
uniform block over the rear half of the upper deck, centred at O (App. G.2.1), gyration radius
0.277 m.
"""

from dataclasses import dataclass
import math

from agv_nodes.world.lm628 import (
    COUNTS_PER_MOTOR_REV,
    LM628,
    SAMPLE_PERIOD,
    acceleration_code,
    counts_per_metre,
    velocity_code,
)
from agv_nodes.world.settings import Concic2Params
from agv_nodes.world.vehicles import Concic2, VehicleState, advance_pose
from agv_nodes.world.wheel_loops import WheelLoops

G = 9.81
TWO_PI = 2.0 * math.pi
LB = 0.45359237  # kg


@dataclass
class Concic2DynamicParams:
    """Parameters of the dynamic CONCIC-II; geometry as Concic2Params."""

    wheel_radius: float = 0.075  # m (Table B.3)
    wheel_span: float = 0.52  # m, L [D]
    caster_distance: float = 0.31  # m, L_a [D]
    caster_trail: float = 0.05  # m, s [D]
    camera_distance: float = 0.64  # m, L_c [D]
    # m/s^2 of the LM628 trapezoid, both wheels [A]: 0 to 0.785 m/s in 2.7 s, within 7.3.2's
    # "less than 7 s"; the thesis's "0.024" (7.3) read through Eq. 6.12 is 0.112 (7.0 s there),
    # the world's concic2.acceleration option (bench/results/concic2_thesis_bench.md).
    acceleration: float = 0.3
    max_wheel_speed: float = 1.14  # m/s (145 rpm, Table B.3)
    mass: float = 273.5 * LB  # kg, Table B.1 (124 kg)
    payload: float = 250.0 * LB  # kg, the experiments' 250 lb (7.3.2)
    yaw_inertia: float = 22.2  # kg m^2 about O, unloaded [D]
    payload_gyration: float = 0.277  # m [A]
    gear_ratio: float = 9.9  # (Table B.3)
    torque_constant: float = 0.114  # N m/A (Eq. B.5)
    back_emf_constant: float = 0.114  # V s/rad [D]
    armature_resistance: float = 0.602  # ohm (Table B.4)
    armature_inductance: float = 0.0047  # H (Table B.4)
    rotor_inertia: float = 0.002  # kg m^2 (Eq. B.12)
    viscous_friction: float = 0.0012  # N m s [D]
    coulomb_friction: float = 0.486  # N m [D]
    rolling_k1: float = 0.007  # (Eq. G.45)
    rolling_k2: float = 0.01  # s/m (Eq. G.45)
    caster_side_friction: float = 0.01  # k_n (Eq. G.49)
    supply_voltage: float = 24.0  # V (Table B.4)
    full_speed_input: float = 4.2  # V at the amplifier input for max_wheel_speed (7.2.1)
    velocity_gain: float = 2.0  # A per rad/s of motor speed, the speed loop [D]
    amplifier_time_constant: float = 0.001  # s (Eq. C.2)
    amplifier_input_limit: float = 7.0  # V (C.1.7.3)
    peak_current: float = 36.0  # A (6.3.3)
    continuous_current: float = 9.0  # A (6.3.3)
    peak_duration: float = 0.39  # s (C.2.3.1)
    dac_volts_per_code: float = 0.09  # V [D]
    kp: int = 225  # LM628 filter, all four (7.3)
    ki: int = 100
    kd: int = 50
    il: int = 30
    derivative_interval: int = 16  # servo samples [A]
    output_shift: int = 16  # [A], see lm628
    cross_coupling: float = 0.0  # 9.2.1, off (wheel_loops)
    cartesian_gain: float = 0.0  # 9.2.2, off (wheel_loops)

    @classmethod
    def from_params(cls, p: Concic2Params) -> 'Concic2DynamicParams':
        """Take the shared geometry and acceleration from the world's Concic2Params."""
        return cls(wheel_radius=p.wheel_radius, wheel_span=p.wheel_span,
                   caster_distance=p.caster_distance, caster_trail=p.caster_trail,
                   camera_distance=p.camera_distance, acceleration=p.acceleration,
                   max_wheel_speed=p.max_wheel_speed, cross_coupling=p.cross_coupling,
                   cartesian_gain=p.cartesian_gain)


class Concic2Dynamic(Concic2):
    """CONCIC-II, Huang's dynamic model with LM628 loops; the interface of vehicles.Concic2."""

    kind = 'concic2'

    def __init__(self, params: Concic2DynamicParams | Concic2Params) -> None:
        if isinstance(params, Concic2Params):
            params = Concic2DynamicParams.from_params(params)
        self.p = p = params
        self.state = VehicleState()
        self.enable = False
        self.radio_stop = False
        self.left_demand = 0.0
        self.right_demand = 0.0
        self.v1 = self.v2 = 0.0  # wheel rim speeds, m/s
        self.i1 = self.i2 = 0.0  # armature currents, A
        self.vt1 = self.vt2 = 0.0  # motor terminal voltages (ohmic drop and back-EMF), V
        self.theta1 = self.theta2 = 0.0  # motor shaft angles, rad (the encoders)
        self.caster_front = self.caster_rear = 0.0  # from the body x axis, rad (CCW +)
        self.overcurrent_time = [0.0, 0.0]
        self._phase = 0.0  # s since the last servo sample
        self.counts_per_m = counts_per_metre(p.wheel_radius, p.gear_ratio)
        acc = acceleration_code(p.acceleration, self.counts_per_m)
        self.left_chip = LM628(acc, p.kp, p.ki, p.kd, p.il, p.derivative_interval,
                               p.output_shift)
        self.right_chip = LM628(acc, p.kp, p.ki, p.kd, p.il, p.derivative_interval,
                                p.output_shift)
        self._target1 = self._target2 = 0.0  # last amplifier input voltages, V
        self._caster_q = (0.0, 0.0)
        self.loops = (WheelLoops(p.cross_coupling, p.cartesian_gain, p.wheel_span,
                                 self.counts_per_m)
                      if p.cross_coupling or p.cartesian_gain else None)
        self._constants()

    def _constants(self) -> None:
        p = self.p
        n_r = p.gear_ratio / p.wheel_radius
        half = p.wheel_span / 2.0
        m = p.mass + p.payload
        iz = p.yaw_inertia + p.payload * p.payload_gyration ** 2
        m_v = m + 2.0 * n_r * n_r * p.rotor_inertia
        m_w = iz + 2.0 * n_r * n_r * half * half * p.rotor_inertia
        a, c = m_v / 4.0 + m_w / (4.0 * half * half), m_v / 4.0 - m_w / (4.0 * half * half)
        det = a * a - c * c
        self._minv = (a / det, -c / det)  # wheel-coordinate inverse mass matrix (symmetric)
        self._n_r = n_r
        self._l = half
        self._normal = m * G / 4.0  # N on each wheel and caster (Eq. G.1)
        self._rad_per_count = 2.0 * math.pi / COUNTS_PER_MOTOR_REV
        self._tf_n = p.coulomb_friction * n_r
        self._roll = p.rolling_k1 * self._normal
        self._side = p.caster_side_friction * self._normal
        self._pivot_front = p.caster_distance + p.caster_trail
        self._pivot_rear = -(p.caster_distance - p.caster_trail)
        # abs(u) above (c1 + c2) * bound keeps every Gauss-Seidel iterate at its limit: ma c1
        # + |mc| c2 <= max(ma, |mc|) (c1 + c2), with a margin for rounding.
        self._stick_margin = max(self._minv[0], abs(self._minv[1])) * (1.0 + 1e-9)
        self._lag_full = math.exp(-SAMPLE_PERIOD / p.amplifier_time_constant)
        # Current per input volt: full_speed_input holds max_wheel_speed against the speed loop.
        self._input_gain = p.velocity_gain * p.max_wheel_speed * n_r / p.full_speed_input
        # Amplifier input voltage for each DAC code (-128..127).
        lim = p.amplifier_input_limit
        self._volts = [min(max(code * p.dac_volts_per_code, -lim), lim)
                       for code in range(-128, 128)]
        self.m_v, self.m_w = m_v, m_w

    def set_wheels(self, left: float, right: float, enable: bool) -> None:
        """Latch the wheel speed demands (m/s) into the two LM628s."""
        super().set_wheels(left, right, enable)
        self.left_chip.load_velocity(velocity_code(self.left_demand, self.counts_per_m))
        self.right_chip.load_velocity(velocity_code(self.right_demand, self.counts_per_m))

    def wheel_speeds(self) -> tuple[float, float]:
        """Wheel rim speeds, left and right, m/s."""
        return self.v1, self.v2

    def _gate(self) -> bool:
        """Turn the chips on or off to follow enable and the radio stop; True when powered."""
        if not self.enable or self.radio_stop:
            self.left_chip.motor_off()
            self.right_chip.motor_off()
            if self.loops is not None:
                self.loops.reset()
            return False
        for chip, theta, v in ((self.left_chip, self.theta1, self.v1),
                               (self.right_chip, self.theta2, self.v2)):
            if chip.off:
                chip.start(math.floor(theta / self._rad_per_count),
                           v * self.counts_per_m * SAMPLE_PERIOD)
        return True

    def step(self, dt: float) -> None:
        """Advance by dt seconds: servo samples every 341 us, the mechanics in between.

        One loop for both wheels over the servo intervals the step spans; between samples the
        DAC output is held, the current follows the speed loop's demand in closed form (the
        lag's exponential over a full interval precomputed) and the body takes one explicit
        step.
        """
        drive = self._gate()
        self._casters(dt)
        p = self.p
        powered = not self.radio_stop
        n_r, kt, ke, r_a = self._n_r, p.torque_constant, p.back_emf_constant, p.armature_resistance
        b, l_arm, supply = p.viscous_friction, p.armature_inductance, p.supply_voltage
        g_in, g_v = self._input_gain, p.velocity_gain
        i_cont, i_peak, t_peak = p.continuous_current, p.peak_current, p.peak_duration
        ma, mc = self._minv
        q1, q2 = self._caster_q
        tf_n, roll, k2 = self._tf_n, self._roll, p.rolling_k2
        bound = self._stick_margin
        rpc, table, span = self._rad_per_count, self._volts, p.wheel_span
        lag_full, tau = self._lag_full, p.amplifier_time_constant
        left, right = self.left_chip, self.right_chip
        v1, v2, i1, i2 = self.v1, self.v2, self.i1, self.i2
        th1, th2 = self.theta1, self.theta2
        o1, o2 = self.overcurrent_time
        in1, in2 = (self._target1, self._target2) if drive else (0.0, 0.0)
        phase = self._phase
        x0 = h0 = 0.0  # forward travel and heading change over dt, body frame
        remaining = dt
        while remaining > 1e-12:
            if phase <= 1e-12:  # a servo sample is due
                pos1, pos2 = math.floor(th1 / rpc), math.floor(th2 / rpc)
                if self.loops is not None and drive:  # 9.2: each chip's error corrected
                    c1, c2 = self.loops.corrections(left, right, pos1, pos2)
                    pos1, pos2 = pos1 - c1, pos2 - c2
                self._target1 = table[left.sample(pos1) + 128]
                self._target2 = table[right.sample(pos2) + 128]
                if drive:
                    in1, in2 = self._target1, self._target2
            h = SAMPLE_PERIOD - phase if SAMPLE_PERIOD - phase <= remaining else remaining
            lag = lag_full if h == SAMPLE_PERIOD else math.exp(-h / tau)
            w1 = v1 * n_r  # motor speeds, rad/s
            w2 = v2 * n_r
            if powered:
                # The speed loop asks for a current, the current loop follows it behind its lag
                # within the limits, and no faster than the supply can drive the armature.
                lim = i_peak if o1 < t_peak else i_cont
                target = min(max(g_in * in1 - g_v * w1, -lim), lim)
                back = r_a * i1 + ke * w1
                i1 = min(max(target + (i1 - target) * lag, i1 + (-supply - back) / l_arm * h),
                         i1 + (supply - back) / l_arm * h)
                o1 = o1 + h if abs(i1) > i_cont else 0.0
                lim = i_peak if o2 < t_peak else i_cont
                target = min(max(g_in * in2 - g_v * w2, -lim), lim)
                back = r_a * i2 + ke * w2
                i2 = min(max(target + (i2 - target) * lag, i2 + (-supply - back) / l_arm * h),
                         i2 + (supply - back) / l_arm * h)
                o2 = o2 + h if abs(i2) > i_cont else 0.0
            else:  # relays open: the armature carries no current
                i1 = i2 = 0.0
            f1 = (kt * i1 - b * w1) * n_r + q1
            f2 = (kt * i2 - b * w2) * n_r + q2
            u1 = v1 + (ma * f1 + mc * f2) * h
            u2 = v2 + (mc * f1 + ma * f2) * h
            # Coulomb friction (motor T_f and rolling resistance) as impulses bounded by their
            # limits: projected Gauss-Seidel on the two wheels, so a wheel that would cross
            # zero stops there and sticks while the drive cannot overcome the limit.
            c1 = (tf_n + roll * (1.0 + k2 * abs(v1))) * h
            c2 = (tf_n + roll * (1.0 + k2 * abs(v2))) * h
            if abs(u1) > (c1 + c2) * bound and abs(u2) > (c1 + c2) * bound:
                # Both wheels keep moving: each impulse sits at its limit, whatever the other.
                j1 = -c1 if u1 > 0.0 else c1
                j2 = -c2 if u2 > 0.0 else c2
            else:
                j1 = j2 = 0.0
                for _ in range(3):
                    j1 = min(max(-(u1 + mc * j2) / ma, -c1), c1)
                    j2 = min(max(-(u2 + mc * j1) / ma, -c2), c2)
            n1 = u1 + ma * j1 + mc * j2
            n2 = u2 + mc * j1 + ma * j2
            if abs(n1) < 1e-12:  # what the bounded impulses leave of a stop
                n1 = 0.0
            if abs(n2) < 1e-12:
                n2 = 0.0
            th1 += 0.5 * (v1 + n1) * n_r * h
            th2 += 0.5 * (v2 + n2) * n_r * h
            x0 += 0.25 * (v1 + n1 + v2 + n2) * h
            h0 += 0.5 * (n2 - n1 + v2 - v1) / span * h
            v1, v2 = n1, n2
            remaining -= h
            phase += h
            if phase >= SAMPLE_PERIOD - 1e-12:
                phase = 0.0
        self.v1, self.v2, self.i1, self.i2 = v1, v2, i1, i2
        self.vt1 = r_a * i1 + ke * v1 * n_r
        self.vt2 = r_a * i2 + ke * v2 * n_r
        self.theta1, self.theta2 = th1, th2
        self.overcurrent_time = [o1, o2]
        self._phase = phase
        s = self.state
        advance_pose(s, x0 / dt if dt > 0.0 else 0.0, h0 / dt if dt > 0.0 else 0.0, dt)
        s.speed = 0.5 * (v1 + v2)
        s.yaw_rate = (v2 - v1) / span

    def _casters(self, dt: float) -> None:
        """Swivel both casters over dt and set their forces on the wheels for this step."""
        v = 0.5 * (self.v1 + self.v2)
        w = (self.v2 - self.v1) / self.p.wheel_span
        s, k2 = self.p.caster_trail, self.p.rolling_k2
        roll, side = self._roll, self._side
        fx = m_z = 0.0
        x_p = self._pivot_front
        delta = self.caster_front
        for front in (True, False):
            if not front:
                self.caster_front = delta
                x_p = self._pivot_rear
                delta = self.caster_rear
            vy = w * x_p
            speed = math.hypot(v, vy)
            if speed > 1e-6:
                alpha = math.atan2(vy, v)
                # Steady misalignment where the swivel rate cancels the body's yaw rate.
                ratio = min(max(w * s / speed, -1.0), 1.0) if s > 0.0 else 0.0
                d_star = -math.asin(ratio)
                d = math.remainder(delta - alpha - d_star, TWO_PI)
                k = math.exp(-speed * dt / s) if s > 0.0 else 0.0
                delta = alpha + d_star + 2.0 * math.atan(math.tan(0.5 * d) * k)
                # Rolling resistance against the contact's travel along the heading.
                cd, sd = math.cos(delta), math.sin(delta)
                along = v * cd + vy * sd
                f_roll = (-math.copysign(roll * (1.0 + k2 * abs(along)), along)
                          if abs(along) > 1e-6 else 0.0)
                mis = math.remainder(alpha - delta, TWO_PI)
                f_side = -math.copysign(side, mis) if abs(mis) > 1e-6 else 0.0
                fx += f_roll * cd + f_side * -sd
                m_z += x_p * (f_roll * sd + f_side * cd)
        self.caster_rear = delta
        l2 = 2.0 * self._l
        self._caster_q = (0.5 * fx - m_z / l2, 0.5 * fx + m_z / l2)


def motor_voltage_step(p: Concic2DynamicParams, volts: float, duration: float,
                       locked: bool = False, h: float = 1e-4) -> list[tuple[float, float, float]]:
    """Return (t, current, shaft speed) of one free motor after a terminal-voltage step.

    The motor alone, off the truck (App. B.5): rotor inertia, viscous and Coulomb friction and
    the armature circuit, integrated with the same closed-form armature step as the vehicle.
    `locked` holds the shaft (the electrical time constant).
    """
    kt, ke, r_a = p.torque_constant, p.back_emf_constant, p.armature_resistance
    decay = math.exp(-h * r_a / p.armature_inductance)
    i = w = 0.0
    out = []
    for k in range(int(round(duration / h))):
        i_ss = (volts - ke * w) / r_a
        i = i_ss + (i - i_ss) * decay
        if not locked:
            torque = kt * i - p.viscous_friction * w
            w_new = w + torque / p.rotor_inertia * h
            stop = p.coulomb_friction / p.rotor_inertia * h
            w = (w_new - math.copysign(stop, w_new)) if abs(w_new) > stop else 0.0
        out.append(((k + 1) * h, i, w))
    return out
