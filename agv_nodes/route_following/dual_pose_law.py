"""Our dual-camera law: the truck's pose from both windows, and a shaped turn onto the tape.

Not the thesis's: Rajagopalan 1991, Sec. 5.3 steers from a weighted sum of the window offsets
(Eq. 5.19-5.22, dual_camera.py). Here the two windows, at +L_c and -L_c about the drive axle,
are read as a measurement of the whole pose against the tape, and the caster angle is chosen
from that pose (DualCameraParams law = pose). In the frame of travel (dual_camera.travel_frame)
with w_f = -e_df and w_r = -e_dr the leading and trailing window centres' offsets left of the
tape, the axle's offset y and heading psi against the chord through both windows are

    y = (w_f + w_r) / 2,    sin(psi) = (w_f - w_r) / (2 L_c),

and on a curve of curvature kappa each window sees the tape turned by about +-L_c kappa from
the chord, so kappa = (e_tf - e_tr) / (2 L_c) (the orientation difference of Eq. 5.21-5.22).
Both windows on the tape (w_f = w_r = 0) is the chord pose of Eq. 5.17-5.18 on any curve.

The law works in distance travelled, where the truck's kinematics do not depend on speed: the
path curvature c = tan(theta_s) / L_ae (Eq. 5.10-5.11) turns the heading at d(psi)/ds = c -
kappa, and d(y)/ds = sin(psi). It asks for a heading set by the offset, bounded, and turns to
it at a rate per metre:

    psi_ref = -clip(y / (4 zeta^2 l), psi_max, (|y| + lead_margin) / L_c),
    c = kappa + (psi_ref - psi) / l,

l = max(turn_distance, speed * turn_time): one pole at 1 / l per metre from the heading loop,
the other set by the damping zeta in the linear range. Far from the tape the heading holds at
psi_max, which keeps the leading window from swinging past the tape by more than L_c psi_max
minus the offset left, and brings the trailing window in while the axle is still moving (a
plain offset feedback first swings it out, then brings it in after the axle). The time floor
turn_time * speed keeps the loop inside what a frame every 50 ms and the wheels' lag allow,
whatever the speed.

Delays. The pose is measured at the frame; the wheels reach the new speeds a wheel lag later
and the command holds for a frame. The law predicts the pose `predict` s ahead with the yaw
rate the wheels are estimated to be turning at (the commands it gave, through a first-order lag
of wheel_lag s and the drive's yaw acceleration limit) and steers that pose.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from agv_nodes.route_following.settings import DualCameraParams, SteeringParams


@dataclass
class Pose:
    """The axle's pose against the tape's chord, in the frame of travel."""

    y: float  # m, + = the axle left of the tape
    psi: float  # rad, + = heading turned counter-clockwise from the chord
    kappa: float  # 1/m, + = the tape turns left


def pose_of(lead_d: float, lead_theta: float, trail_d: float, trail_theta: float,
            camera: float) -> Pose:
    """Return the pose from travel-frame offsets (e_d, e_theta) of the two windows."""
    w_f, w_r = -lead_d, -trail_d
    s = max(-1.0, min(1.0, (w_f - w_r) / (2.0 * camera)))
    return Pose((w_f + w_r) / 2.0, math.asin(s), (lead_theta - trail_theta) / (2.0 * camera))


class PoseLaw:
    """State feedback on the measured pose, one frame pair at a time (see the module docstring)."""

    def __init__(self, params: DualCameraParams, steering: SteeringParams,
                 camera: float) -> None:
        self.p, self.s, self.camera = params, steering, camera
        self.reset()

    def reset(self) -> None:
        """Forget the history: the wheels are taken to turn at the yaw rate of a straight run."""
        self.kappa = None  # filtered curvature
        self.rate = 0.0  # estimated yaw rate, rad/s
        self.command = 0.0  # last yaw rate asked for, rad/s
        self.pose: Pose | None = None

    def caster_angle(self, curvature: float) -> float:
        """Return theta_s whose path curvature is `curvature` (Eq. 5.10-5.11 inverted)."""
        s = self.s
        theta = math.atan(curvature * s.caster_distance)
        for _ in range(3):  # L_ae grows with the caster angle by the trail
            theta = math.atan(curvature * (s.caster_distance
                                           + s.caster_trail * (1.0 - math.cos(theta))))
        return max(-s.max_angle, min(s.max_angle, theta))

    def _advance(self, dt: float) -> None:
        """Move the wheels' estimated yaw rate on by dt towards the last command."""
        p = self.p
        limit = p.pose_yaw_acceleration * dt
        target = self.rate + max(-limit, min(limit, self.command - self.rate))
        self.rate += (target - self.rate) * (1.0 - math.exp(-dt / p.pose_wheel_lag))

    def steer(self, pose: Pose, dt: float, speed: float) -> float:
        """Return theta_s (rad, clipped) for a measured pose at cruise `speed` (m/s)."""
        p = self.p
        self._advance(dt)
        a = p.pose_curvature_filter
        self.kappa = pose.kappa if self.kappa is None else self.kappa + a * (pose.kappa
                                                                           - self.kappa)
        v = max(speed, 1e-3)
        # The predictor: the heading turns at the wheels' rate relative to the chord.
        h = p.pose_predict
        psi = pose.psi + (self.rate - v * self.kappa) * h
        y = pose.y + v * h * math.sin(0.5 * (pose.psi + psi))
        self.pose = Pose(y, psi, self.kappa)
        length = max(p.pose_turn_distance, v * p.pose_turn_time)
        lateral = y / (4.0 * p.pose_damping ** 2 * length)
        psi_ref = -max(-p.pose_max_heading, min(p.pose_max_heading, lateral))
        # No heading that puts the leading window more than lead_margin past the tape.
        reach = (abs(y) + p.pose_lead_margin) / self.camera
        psi_ref = max(-reach, min(reach, psi_ref))
        curvature = self.kappa + (psi_ref - psi) / length
        theta = self.caster_angle(curvature)
        s = self.s
        self.command = v * math.tan(theta) / (s.caster_distance
                                              + s.caster_trail * (1.0 - math.cos(theta)))
        return theta
