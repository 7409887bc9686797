"""The proposals of Rajagopalan 1991, Chapter 9, as laws of their own (system 15), ROS-free.

The thesis built none of them ("Recommendations for future work"); each is read here from its
section and equations, with the printing faults the digest lists
(/work/shared/docs/seed-rajagopalan-1991-spec.md, 2.8) settled as said at each function.
Signs are route following's (camera_guidance.py): eps_d > 0 with the tape left of the window,
theta_s > 0 a left turn; wheel 1 is the left wheel, wheel 2 the right.

Two of them steer when their option (route_following `chapter9.*`, all off by default) is on,
each in place of one part of the single-camera law (`steering_law` builds it):

- chapter9.speed_reference, the speed-dependent law of 9.3, "to provide a variable corrective
  action as a function of speed", in the reading chapter9.speed_form (SpeedScaledSteering);
- chapter9.inflexion_curvature, the inflexion points of 9.5: the window predictor's curvature
  estimate restarts where the tape's concavity changes sign, instead of filtering through it.

The rest are the equations alone, for benches and tests: the wheel-speed increments of
Eq. 9.7-9.10 and the reference point of 9.6 (Eq. 9.15-9.16). The wheel loops of 9.2 belong to
the drive, not to route following: agv_nodes/world/wheel_loops.py, world options.
"""

from __future__ import annotations

from dataclasses import replace
import math

from agv_nodes.route_following.camera_guidance import (
    CameraSteering,
    Measurement,
    WindowPredictor,
)
from agv_nodes.route_following.settings import Chapter9Params, SteeringParams


def speed_law_increments(speed: float, eps_theta_desired: float, eps_theta_actual: float,
                         gain_1: float, gain_2: float, l1: float, l2: float, radius: float,
                         caster_distance: float, trail: float) -> tuple[float, float]:
    """Return the wheels' angular-speed increments (d_omega_1, d_omega_2), rad/s (Eq. 9.9-9.10).

    Eq. 9.5 gives the yaw-rate increment, d_theta_r [(L_a - s) / s - G2] = V G1 {1 / sin
    eps_thetad - 1 / cos eps_thetaa}; Eq. 9.6 ties it to the wheels, d_theta_r = r (d_omega_1
    - d_omega_2) / (L1 + L2) (Eq. 9.7 as printed turns -G2 into +G2: the derivation's sign
    is kept); Eq. 9.8, L1 d_omega_1 + L2 d_omega_2 = 0, keeps the speed. Wheel 1 and the
    yaw's sign are the thesis's: d_omega_1 > d_omega_2 turns the truck as d_theta_r > 0.
    Eq. 9.10 as printed is labelled d_omega_1 and has lost its minus sign. 1 / sin
    eps_thetad is unbounded as the desired angle goes to 0 (a straight): ValueError there.
    """
    if math.sin(eps_theta_desired) == 0.0:
        raise ValueError('Eq. 9.2 needs a desired orientation offset other than 0 (1 / sin)')
    lever = (caster_distance - trail) / trail - gain_2  # Eq. 9.5
    rate = speed * gain_1 * (1.0 / math.sin(eps_theta_desired)
                             - 1.0 / math.cos(eps_theta_actual))
    difference = (l1 + l2) * rate / (radius * lever)  # Eq. 9.7 with Eq. 9.5's sign
    return l2 * difference / (l1 + l2), -l1 * difference / (l1 + l2)  # Eq. 9.9-9.10


def reference_offset_thesis(eps_df: float, eps_dr: float, l1: float, l2: float) -> float:
    """Return y_c as printed: Eq. 9.15 (same signs) or Eq. 9.16 (opposite), thesis signs.

    The offsets are the thesis's own (its rear camera reads with the opposite sign, digest
    section 0). c is l1 behind the front window and l2 ahead of the rear one.
    """
    share = abs(eps_df + eps_dr) * l1 / (l1 + l2)
    if math.copysign(1.0, eps_df) == math.copysign(1.0, eps_dr):
        return (share + min(abs(eps_df), abs(-eps_dr))) * math.copysign(1.0, eps_df)
    return share * math.copysign(1.0, eps_df) - eps_dr


def reference_offset(eps_df: float, eps_dr: float, l1: float, l2: float) -> float:
    """Return the tape's offset at c, l1 behind the front window, both offsets in the body frame.

    Both perpendiculars are drawn across the truck's axis (9.6, Fig. 9.4), so along a straight
    tape the offset is linear in the distance along the axis: the interpolation between them.
    """
    return eps_df + (eps_dr - eps_df) * l1 / (l1 + l2)


def concavity(second_derivative: float, dead: float = 0.0) -> int:
    """Return +1 (concave upwards), -1 (downwards) or 0 (|f''| within `dead`) (Sec. 9.5)."""
    if abs(second_derivative) <= dead:
        return 0
    return 1 if second_derivative > 0 else -1


class InflexionDetector:
    """A change of concavity (Sec. 9.5), confirmed over `frames` readings in a row.

    f'' = 0 is necessary for an inflexion, not sufficient (the thesis's own caution): a reading
    of the other sign counts only beyond `dead`, and only `frames` of them in a row make an
    inflexion; readings within `dead` neither count nor break the run.
    """

    def __init__(self, dead: float, frames: int) -> None:
        self.dead, self.frames = dead, frames
        self.sign = 0  # the concavity held
        self._run: list[float] = []  # readings of the other sign in a row
        self.mean = 0.0  # of the run that confirmed the last inflexion

    def reset(self) -> None:
        """Forget the concavity held."""
        self.sign, self._run = 0, []

    def update(self, second_derivative: float) -> bool:
        """Take one reading of f''; return True at a confirmed change of concavity."""
        sign = concavity(second_derivative, self.dead)
        if sign == 0:
            return False
        if self.sign == 0:
            self.sign = sign
            return False
        if sign == self.sign:
            self._run = []
            return False
        self._run.append(second_derivative)
        if len(self._run) < self.frames:
            return False
        self.mean = sum(self._run) / len(self._run)
        self.sign, self._run = sign, []
        return True


class InflexionPredictor(WindowPredictor):
    """The window predictor whose curvature restarts at an inflexion of the tape (Sec. 9.5).

    The tape's curvature at the window is the f'' of 9.5 along the tape. The predictor filters
    each frame's reading (a share curvature_filter); through an S-bend's inflexion the filtered
    value keeps the old arc's sign for some frames and predicts the wrong way. Here a confirmed
    change of sign sets the estimate to the mean of the readings that confirmed it.
    """

    def __init__(self, params: SteeringParams, camera: float, options: Chapter9Params) -> None:
        super().__init__(params, camera)
        self.detector = InflexionDetector(options.inflexion_curvature, options.inflexion_frames)

    def forget(self) -> None:
        """Forget the last frame's angle and the concavity held."""
        super().forget()
        self.detector.reset()

    def reset(self) -> None:
        """Start from rest on a straight."""
        super().reset()
        self.detector.reset()

    def predict(self, eps_d: float, eps_theta: float, dt: float, speed: float,
                plain: bool = True) -> tuple[float, float]:
        """Return (eps_d, eps_theta) `predict` s on, the curvature restarted at an inflexion.

        `plain`: the frame shows plain tape (a road sign's frame is no reading, as the parent's).
        """
        if self.p.predict > 0 and speed > 0 and plain and self._alpha is not None:
            reading = ((eps_theta - self._alpha) / dt + self.rate) / speed  # as the parent's,
            bound = 1.0 / self.camera  # within the parent's bound
            if self.detector.update(max(-bound, min(bound, reading))):
                # The confirming readings' mean; the parent's filter then moves it on.
                self.kappa = self.detector.mean
        return super().predict(eps_d, eps_theta, dt, speed, plain)


class SpeedScaledSteering(CameraSteering):
    """The P terms' gains scaled with the cruise speed (Sec. 9.3), the integral's left as it is.

    9.3 differentiates the P law (Eq. 9.1), finds the closing rate of eps_d proportional to the
    speed (Eq. 9.2) and the wheel increments of Eq. 9.9-9.10 carrying V G1. Eq. 5.15-5.16
    already make the wheels' differential V tan(theta_s) / L_ae, so that V is the plain law's
    (form once, which steering_law builds as the plain law). The two other readings, named:
    `gains`, the gains x V / V_ref (V twice in the wheels); `per_time`, x V_ref / V (the loop's
    time response the same at every speed). At V_ref both are the plain law.
    """

    def __init__(self, params: SteeringParams, camera: float, reference: float,
                 form: str = 'gains') -> None:
        super().__init__(params, camera)
        if form not in ('gains', 'per_time'):
            raise ValueError(f'chapter9.speed_form {form!r}: scaled forms are gains, per_time')
        self.base, self.reference, self.form = self.p, reference, form
        self._scaled: dict[float, SteeringParams] = {}

    def factor(self, speed: float) -> float:
        """Return the gains' factor at cruise `speed` (1 at rest: no yaw to scale)."""
        if speed <= 0.0:
            return 1.0
        return speed / self.reference if self.form == 'gains' else self.reference / speed

    def update(self, m: Measurement, dt: float, speed: float = 0.0) -> float | None:
        """Return the caster angle at cruise `speed` with the P gains scaled by the form."""
        if speed not in self._scaled:
            k = self.factor(speed)
            self._scaled[speed] = replace(self.base, gain_d=self.base.gain_d * k,
                                          gain_theta=self.base.gain_theta * k)
        self.p = self._scaled[speed]
        try:
            return super().update(m, dt, speed)
        finally:
            self.p = self.base


def steering_law(steering: SteeringParams, camera: float, options: Chapter9Params
                 ) -> CameraSteering:
    """Return the single-camera law with the Chapter 9 options on; with all off, the plain one."""
    scaled = options.speed_reference > 0 and options.speed_form != 'once'
    law = (SpeedScaledSteering(steering, camera, options.speed_reference, options.speed_form)
           if scaled else CameraSteering(steering, camera))
    if options.inflexion_curvature > 0:
        law.predictor = InflexionPredictor(steering, camera, options)
    return law
