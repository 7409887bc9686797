"""The National Semiconductor LM628 motion controller of one CONCIC-II wheel, in velocity mode.

As the thesis used it (Rajagopalan 1991, 6.3.2, App. C.1, Eq. 6.1-6.13, 7.3):

- clock 6 MHz (the 12 MHz bus halved), servo sample dt = 2048 / f_CLK = 341 us (Eq. 6.7);
- encoder 1024 lines x 4 (quadrature) on the motor, gear 9.9: 40,550 counts per wheel
  revolution (Eq. 6.4-6.5);
- trajectory generator in velocity mode: 32-bit velocity and acceleration in 16.16 fixed point,
  counts per sample and counts per sample^2 (Eq. 6.8-6.12); the profile velocity moves toward
  the loaded target by the acceleration each sample (the trapezoid of Fig. 6.12) and the desired
  position integrates it; a new target velocity may be loaded at any time, the acceleration
  only while the motor is off or the profile has reached its target (App. C.1.6.3);
- digital PID on the position error e = desired - actual, in counts (Eq. 6.1-6.2):
  u = Kp e + Ki sum(e) (limited by IL) + Kd [e(k') - e(k'-1)], the derivative difference taken
  every derivative sampling interval (1..256 samples, Table C.3) and held in between;
  experimental gains Kp 225, Ki 100, Kd 50, IL 30 (7.3);
- output to an 8-bit DAC (offset binary, code 0 here = mid-scale); "motor off" (Table C.4 bit 8)
  puts out zero and ignores the encoder.

Scalings the thesis does not give, chosen here:

- [A] The 16-bit error is saturated at +-32767 (the chip's 16-bit error register).
- [A] The integral term is Ki * sum(e) / 2^8 and is limited to +-IL * 2^8: the integral gain
  acts at 1/256 of the proportional one per sample, without which Ki = 100 against Kp = 225 at
  2.9 kHz would put the integral corner (~1300 rad/s) above any crossover the wheel allows;
  IL is read as the upper byte of the filter word.
- [A] The filter word reaches the DAC shifted right by `output_shift` = 16 bits. The chip's
  own 8-bit mode takes the top byte of its output word (a shift of 8), but with the thesis
  gains that loop limit-cycles against the wheel's inertia and stiction (tens of % speed
  ripple). With the speed-loop amplifier of concic2_dynamics, 16 puts the loaded truck's
  position loop near the critical damping the thesis tuned for (C.2.3.5): 1 code per 291
  counts (3.4 mm of rim travel), crossover about 7 per s, a differential speed step overshoots
  7 % (15: 19 %, 17: 6 % but 0.33 s to 63 %); with the profile a step the loop's time
  constant is 0.198 s (15: 0.108 s, 17: 0.302 s), within the 0.16-0.24 s that four of the
  thesis's 40-60 ms cycles give (6.3.8). The gains keep the thesis's ratios; the
  integral term, at most IL 2^8 >> 16 = 0.1 code, has no effect at this shift.
- [A] Derivative sampling interval 16 samples (5.5 ms): the thesis does not give its setting;
  the overshoot varies little between 1 and 64.
- [A] On "motor off" the desired position follows the actual one and the profile velocity the
  measured one, so that re-enabling is bumpless (the kinematic model does the same).
"""

import math

F_CLK = 6.0e6  # Hz (Rajagopalan 1991, App. C.1.7.1)
SAMPLE_PERIOD = 2048.0 / F_CLK  # s, 341 us (Eq. 6.7)
ENCODER_LINES = 1024  # per motor revolution (Eq. 6.5)
COUNTS_PER_MOTOR_REV = 4 * ENCODER_LINES  # quadrature
FIXED = 1 << 16  # 16.16 fixed point of the trajectory registers (6.3.2)
DAC_MAX = 127  # 8-bit DAC, offset binary around mid-scale
ERROR_MAX = 32767  # 16-bit position error register


def counts_per_metre(wheel_radius: float, gear_ratio: float) -> float:
    """Return encoder counts per metre of rim travel (Eq. 6.4: SR * GR per wheel revolution)."""
    return COUNTS_PER_MOTOR_REV * gear_ratio / (2.0 * math.pi * wheel_radius)


def velocity_code(speed: float, counts_per_m: float) -> int:
    """Return the 16.16 velocity register for a rim speed in m/s (Eq. 6.8-6.9), signed."""
    return int(round(speed * counts_per_m * SAMPLE_PERIOD * FIXED))


def acceleration_code(acceleration: float, counts_per_m: float) -> int:
    """Return the 16.16 acceleration register for m/s^2 (Eq. 6.11, without the extra x9.9).

    The printed Eq. 6.12 multiplies by the gear ratio twice; counts per sample^2 need it once.
    At least 1, as the chip has no zero acceleration.
    """
    return max(1, int(round(acceleration * counts_per_m * SAMPLE_PERIOD ** 2 * FIXED)))


class LM628:
    """One LM628 in velocity mode: trajectory generator, PID filter and the DAC output code."""

    __slots__ = ('kp', 'ki', 'kd', 'il', 'derivative_interval', 'output_shift', 'acceleration',
                 '_pending_acceleration', 'target', 'profile', 'desired', 'error_sum', 'off',
                 '_d_prev', '_d_term', '_d_count', 'code')

    def __init__(self, acceleration: int, kp: int = 225, ki: int = 100, kd: int = 50,
                 il: int = 30, derivative_interval: int = 16, output_shift: int = 16) -> None:
        self.kp, self.ki, self.kd, self.il = kp, ki, kd, il
        self.derivative_interval = min(max(int(derivative_interval), 1), 256)  # Table C.3
        self.output_shift = output_shift
        self.acceleration = max(1, int(acceleration))
        self._pending_acceleration: int | None = None
        self.target = 0  # 16.16 counts per sample, signed (direction bit + magnitude)
        self.profile = 0  # 16.16 counts per sample: the trapezoid's present velocity
        self.desired = 0  # desired position, counts x 2^16
        self.error_sum = 0
        self.off = True  # after reset the output is off until a trajectory starts
        self._d_prev = 0
        self._d_term = 0
        self._d_count = 0
        self.code = 0  # last DAC code, -128..127 about mid-scale

    def load_velocity(self, code: int) -> None:
        """Load a new target velocity (may be done during motion)."""
        self.target = int(code)

    def load_acceleration(self, code: int) -> None:
        """Load the acceleration; it takes effect only when the chip allows it (App. C.1.6.3)."""
        self._pending_acceleration = max(1, int(code))
        self._apply_acceleration()

    def _apply_acceleration(self) -> None:
        if self._pending_acceleration is not None and (self.off or self.profile == self.target):
            self.acceleration = self._pending_acceleration
            self._pending_acceleration = None

    def motor_off(self) -> None:
        """Turn the motor off: zero output, no feedback (Table C.4, bit 8)."""
        self.off = True
        self.code = 0

    def start(self, position: int, velocity: float) -> None:
        """Start motion from the actual position (counts) and speed (counts per sample)."""
        if self.off:
            self.off = False
            self.desired = position * FIXED
            self.profile = int(round(velocity * FIXED))
            self.error_sum = 0
            self._d_prev = 0
            self._d_term = 0
            self._d_count = 0
            self._apply_acceleration()

    def sample(self, position: int) -> int:
        """Run one servo sample against the encoder count; return the DAC code."""
        if self.off:
            return 0
        a, vp, vt = self.acceleration, self.profile, self.target
        if vp != vt:  # the trapezoid: constant acceleration toward the target
            if vp < vt:
                vp = vp + a if vt - vp > a else vt
            else:
                vp = vp - a if vp - vt > a else vt
            self.profile = vp
            if vp == vt and self._pending_acceleration is not None:
                self._apply_acceleration()
        desired = self.desired + vp
        self.desired = desired
        e = (desired >> 16) - position
        if e > ERROR_MAX:
            e = ERROR_MAX
        elif e < -ERROR_MAX:
            e = -ERROR_MAX
        s = self.error_sum + e
        i_term = (self.ki * s) >> 8
        lim = self.il << 8
        if i_term > lim:  # integration limit: the sum stops growing at the limit
            i_term, s = lim, s - e
        elif i_term < -lim:
            i_term, s = -lim, s - e
        self.error_sum = s
        self._d_count -= 1
        if self._d_count <= 0:
            self._d_count = self.derivative_interval
            self._d_term = self.kd * (e - self._d_prev)
            self._d_prev = e
        code = (self.kp * e + i_term + self._d_term) >> self.output_shift
        if code > DAC_MAX:
            code = DAC_MAX
        elif code < -DAC_MAX - 1:
            code = -DAC_MAX - 1
        self.code = code
        return code
