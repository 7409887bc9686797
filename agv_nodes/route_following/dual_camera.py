"""Dual-camera guidance of Rajagopalan (1991), Sec. 5.3 (Eq. 5.17-5.22), ROS-free.

A second binary camera at -L_c, facing backwards, sees the tape behind the drive axle. The law
steers the caster angle theta_s from both windows' offsets so that the line through the two
window centres lies on the chord of the track between them (Eq. 5.17-5.18), and it picks one
of four laws each frame (Sec. 5.3.3-5.3.5):

    straight, same side:     theta_s = G1 e_df + G2 e_tf + G3 (|e_df| + |e_dr|) sgn(e_df)   5.19
    straight, opposite:      theta_s = G4 e_df + G2 e_tf + G5 (|e_df| - |e_dr|) sgn(e_df)   5.20
    curved, same side:       theta_s = G1 e_df + G2 (e_tf - e_tr) + G3 (...) sgn(e_df)       5.21
    curved, opposite:        theta_s = G4 e_df + G2 (e_tf - e_tr) + G5 (...) sgn(e_df)       5.22

with gains scheduled by whether the front has crossed the tape since setting off (Sec. 5.3.6).

Sign convention. Every offset is in the frame of travel, x along the direction of travel and
y to its left, with the signs of camera_guidance: e_d > 0 when the tape lies left of the window
centre, e_theta > 0 when the tape is turned counter-clockwise, theta_s > 0 turns left. Each
camera's ImageAnalyser reports in its own image frame; a camera facing along travel (the front
camera going forwards, the rear camera going backwards) is already in the travel frame, and the
other one, turned 180 degrees, reports e_d with the opposite sign and e_theta unchanged (a line
keeps its slope when the image is turned half a revolution). `travel_frame` converts; so
"same side" is sgn(e_df) = sgn(e_dr) here, where the thesis, which used the trailing camera's
raw sign, writes sgn(e_df) = -sgn(e_dr) (Fig. 5.2). On a straight track e_tf = e_tr; on a
curve they have opposite signs, as Sec. 5.3.3 says (the printed Eq. 5.18 has equal signs).
Travelling backwards (direction = -1) the rear camera leads: the same law runs in the frame of
travel with the cameras' roles swapped, and `wheel_speeds` maps its output back to the wheels.

DualCameraParams law = pose runs our own law instead (dual_pose_law.py, not the thesis's): the
pose of the truck measured from both windows, and a bounded heading towards the tape.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import enum
import math
from typing import NamedTuple

from agv_nodes.route_following.camera_guidance import CameraSteering, Measurement, Validity
from agv_nodes.route_following.chapter9 import reference_offset
from agv_nodes.route_following.dual_pose_law import PoseLaw, pose_of
from agv_nodes.route_following.settings import DualCameraParams, SteeringParams, TurningParams
from agv_nodes.settings import build, values_of


class Offsets(NamedTuple):
    """One window's offsets in the frame of travel (see the module docstring)."""

    eps_d: float  # m, + = tape left of the window centre
    eps_theta: float  # rad, + = tape turned counter-clockwise


class Law(enum.Enum):
    """The four laws of Sec. 5.3.4-5.3.5, by their equation numbers."""

    STRAIGHT_SAME = '5.19'
    STRAIGHT_OPPOSITE = '5.20'
    CURVED_SAME = '5.21'
    CURVED_OPPOSITE = '5.22'


def travel_frame(front: Offsets, rear: Offsets, direction: int = 1) -> tuple[Offsets, Offsets]:
    """Return (leading, trailing) offsets in the frame of travel from each camera's own reading.

    The camera that faces along travel reads in that frame already; the other is turned 180
    degrees, so its e_d changes sign and its e_theta does not.
    """
    if direction not in (1, -1):
        raise ValueError(f'direction must be +1 or -1, not {direction!r}')
    lead, trail = (front, rear) if direction == 1 else (rear, front)
    return lead, Offsets(-trail.eps_d, trail.eps_theta)


def sign(x: float, band: float = 0.0) -> int:
    """Return -1, 0 or +1; |x| <= band counts as 0."""
    return 0 if abs(x) <= band else (1 if x > 0 else -1)


def is_curved(lead: Offsets, trail: Offsets, deadband: float) -> bool:
    """Curvature test of Sec. 5.3.3: the two orientation offsets have opposite signs."""
    return sign(lead.eps_theta, deadband) * sign(trail.eps_theta, deadband) < 0


@dataclass
class Decision:
    """What the law did on the last frame (for logs and tests)."""

    law: Law = Law.STRAIGHT_SAME
    same_side: bool = True
    curved: bool = False
    crossed: bool = False  # the leading window has crossed the tape since setting off
    gain: float = 0.0  # G1 or G4 (or G3, per eq522_gain) as applied
    theta_s: float = 0.0


class DualCameraGuidance:
    """The dual-camera law with its gain schedule, one frame pair at a time."""

    def __init__(self, params: DualCameraParams | None = None,
                 steering: SteeringParams | None = None,
                 turning: TurningParams | None = None) -> None:
        self.p = params or DualCameraParams()
        build(DualCameraParams, values_of(self.p))  # SettingError: a value out of its range
        # The geometry, caster limit and absent-frame count are the single-camera law's.
        self.steering = CameraSteering(steering or SteeringParams())
        # L_c, both windows' distance from the axle centre (the junction turn's camera_ahead)
        self.camera_ahead = (turning or TurningParams()).camera_ahead
        self.pose_law = PoseLaw(self.p, self.steering.p, self.camera_ahead)
        self.reference_point = 0.0  # m behind the lead: the gains' switch (chapter9.py, 9.6)
        self.direction = 1
        self.reset()

    def reset(self) -> None:
        """Forget the history: the next frame pair is a start from rest (Sec. 5.3.6)."""
        self.start_sign = 0  # side of the leading window at the start; 0: not yet seen
        self.same_side = True
        self.integral = 0.0
        self.decision = Decision()
        self._last: dict[str, Offsets | None] = {'front': None, 'rear': None}
        self._absent = {'lead': 0, 'trail': 0}
        self.pose_law.reset()

    def gains(self, same_side: bool, curved: bool, crossed: bool) -> tuple[float, float]:
        """Return (first gain, G2) for a situation, by the rules of Sec. 5.3.6."""
        p = self.p
        g2 = p.g2_curve if curved else p.g2_straight
        if same_side:
            if crossed:
                return p.g1_low, g2
            return (p.g1_start_curve if curved else p.g1_start), g2
        g4 = p.g4_low if crossed else p.g4_start
        if curved and p.eq522_gain == 'g3':
            return p.g3, g2
        return g4, g2

    def steer(self, lead: Offsets, trail: Offsets, dt: float) -> float:
        """Return theta_s (rad, clipped) from travel-frame offsets; advance the gain schedule."""
        p = self.p
        s_lead, s_trail = sign(lead.eps_d), sign(trail.eps_d)
        if s_lead and s_trail:
            self.same_side = s_lead == s_trail
        if self.reference_point:  # Rajagopalan 1991, 9.6: the switch at c, not the front end
            s_lead = sign(reference_offset(lead.eps_d, trail.eps_d, self.reference_point,
                                           2.0 * self.camera_ahead - self.reference_point))
        # Exactly on the tape, a window has no side: the last judgement stands.
        if not self.start_sign:
            self.start_sign = s_lead
        crossed = self.decision.crossed or (s_lead != 0 and self.start_sign != 0
                                            and s_lead != self.start_sign)
        curved = is_curved(lead, trail, p.curvature_deadband)
        gain, g2 = self.gains(self.same_side, curved, crossed)
        if not curved:
            orientation = lead.eps_theta
        elif p.orientation_term == 'difference':
            orientation = lead.eps_theta - trail.eps_theta
        else:
            orientation = (lead.eps_theta + trail.eps_theta) / 2.0
        magnitude_sign = sign(lead.eps_d)
        if self.same_side:
            extra = p.g3 * (abs(lead.eps_d) + abs(trail.eps_d)) * magnitude_sign
            law = Law.CURVED_SAME if curved else Law.STRAIGHT_SAME
        else:
            extra = p.g5 * (abs(lead.eps_d) - abs(trail.eps_d)) * magnitude_sign
            law = Law.CURVED_OPPOSITE if curved else Law.STRAIGHT_OPPOSITE
        theta = gain * lead.eps_d + g2 * orientation + extra
        if p.integral:
            if not p.integral_band or abs(lead.eps_d) < p.integral_band:
                self.integral += dt * lead.eps_d  # Eq. 5.6's form, with Delta-T
            theta += p.gain_i * self.integral
        limit = self.steering.p.max_angle
        theta = max(-limit, min(limit, theta))
        self.decision = Decision(law, self.same_side, curved, crossed, gain, theta)
        return theta

    def _fresh(self, end: str, m: Measurement) -> bool:
        """Book one camera's frame; return False when it has been absent too long."""
        if m.validity is Validity.ABSENT:
            self._absent[end] += 1
            return self._absent[end] < self.steering.p.absent_frames
        self._absent[end] = 0
        return True

    def update(self, front: Measurement, rear: Measurement, dt: float,
               direction: int = 1, speed: float | None = None) -> float | None:
        """Return theta_s in the frame of travel for one frame pair, or None to stop.

        `front` and `rear` are each camera's ImageAnalyser reading in its own image frame;
        `direction` is +1 travelling forwards (front camera leads), -1 backwards (rear leads).
        A change of direction is a new leg: the gain schedule starts again. A saturated frame,
        or an absent one before absent_frames of them, repeats that camera's last reading
        (Rajagopalan 1991, 6.3.11); the leading camera absent for absent_frames stops the
        vehicle, the trailing one stops it or leaves the leading camera alone (trailing_lost).
        `speed`: the cruise, m/s, which law = pose needs; the thesis law ignores it.
        """
        if direction != self.direction:
            self.direction = direction
            self.reset()
        lead_m, trail_m = (front, rear) if direction == 1 else (rear, front)
        if not self._fresh('lead', lead_m):
            return None
        trail_ok = self._fresh('trail', trail_m)
        if not trail_ok and self.p.trailing_lost == 'stop':
            return None
        for name, m in (('front', front), ('rear', rear)):
            if m.validity in (Validity.NORMAL, Validity.WIDE):
                self._last[name] = Offsets(m.eps_d, m.eps_theta)
        front_o, rear_o = self._last['front'], self._last['rear']
        if front_o is None or rear_o is None or not trail_ok:
            lead_o = front_o if direction == 1 else rear_o
            if lead_o is None:
                return self.decision.theta_s
            if self.p.law == 'pose':  # the heading from the leading window's angle alone
                return self._pose(lead_o, Offsets(lead_o.eps_d - 2.0 * self.camera_ahead
                                                  * math.sin(lead_o.eps_theta),
                                                  lead_o.eps_theta), dt, speed)
            # trailing_lost = lead_only (or no trailing reading yet): a P law on the lead.
            p, limit = self.p, self.steering.p.max_angle
            theta = p.g1_low * lead_o.eps_d + p.g2_straight * lead_o.eps_theta
            self.decision = replace(self.decision, theta_s=max(-limit, min(limit, theta)))
            return self.decision.theta_s
        lead, trail = travel_frame(front_o, rear_o, direction)
        if self.p.law == 'pose':
            return self._pose(lead, trail, dt, speed)
        return self.steer(lead, trail, dt)

    def _pose(self, lead: Offsets, trail: Offsets, dt: float, speed: float | None) -> float:
        if speed is None:
            raise ValueError('the pose law (DualCameraParams law pose) needs the cruise speed')
        # our pose law (dual_pose_law.py) from travel-frame offsets
        pose = pose_of(lead.eps_d, lead.eps_theta, trail.eps_d, trail.eps_theta,
                       self.camera_ahead)
        theta = self.pose_law.steer(pose, dt, speed)
        self.decision = replace(self.decision, theta_s=theta)
        return theta

    def wheel_speeds(self, speed: float, theta_s: float, direction: int = 1
                     ) -> tuple[float, float]:
        """Return (left, right) rim speeds, m/s, + = forwards, by Eq. 5.10-5.16.

        `speed` >= 0 is the cruise along the direction of travel and theta_s the caster angle
        in the frame of travel. Backwards, the vehicle's left wheel is the travel frame's right
        and a left turn of travel is still counter-clockwise: the body's wheels are Eq. 5.15-5.16
        at -speed and -theta_s.
        """
        if direction == 1:
            return self.steering.wheel_speeds(speed, theta_s)
        return self.steering.wheel_speeds(-speed, -theta_s)
