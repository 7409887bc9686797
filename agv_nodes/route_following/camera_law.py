"""Camera mode's steering: the leading camera alone, or both cameras (Rajagopalan 1991, 5.2-5.3).

The CONCIC-II carries two binary cameras: the front one at +L_c facing forwards and the rear one
at -L_c facing backwards (Rajagopalan 1991, 5.3). Each frame is read by that camera's own
ImageAnalyser in its own image frame (row 0 at the window's far edge, column 0 at its left).
The camera facing along travel leads: the front one going forwards, the rear one in reverse.

Backwards along the tape. Take the frame of travel, x along the direction of travel and y to its
left: going backwards it is the body frame turned half a revolution (x_t = -x_b, y_t = -y_b).
The rear camera faces that way, so its image already reads in the frame of travel with the
signs of Rajagopalan 1991, 5.2: eps_d > 0 with the tape left of travel, eps_theta > 0 with it
turned counter-clockwise. The law gives a caster angle theta_t > 0 to turn the direction of
travel left. A half revolution keeps the sense of rotation, so that is a counter-clockwise yaw
rate psi' = v tan(theta_t) / L_ae in both frames (Eq. 5.10-5.11, at cruise v >= 0 along
travel). Eq. 5.12-5.14 give the wheels of the frame of travel, v - psi' L / 2 on its left and
v + psi' L / 2 on its right; the body's left wheel is the travel frame's right one, and its
forward speed the negative:

    body (left, right) = (-v - psi' L / 2, -v + psi' L / 2)
                       = Eq. 5.15-5.16 at speed -v and caster angle -theta_t,

which is DualCameraGuidance.wheel_speeds for direction -1. The windows sit at +-L_c about the
axle, so the loop backwards is the forward loop mirrored: the same gains and damping.

`cameras` chooses the law (App. F.5 had keys for the front, the rear or both cameras):
  lead: the leading camera's P or PI law (Eq. 5.4 / 5.6); the trailing camera's frames are not
        even analysed.
  both: the dual-camera law (Eq. 5.19-5.22, dual_camera.py) on the two frames of one instant,
        whenever both windows see the tape; otherwise the leading camera's law. The trailing
        window is off the tape at a leg's start near a tape's end and for L_c after each spin
        onto a branch, so a stop for it (the dual law's trailing_lost = stop) would end those
        legs: here it hands over to the leading camera instead.

`camera_law` feed_forward (the parameter, or a leg's own choice in route_command, read when the
leg begins: App. F.5 had identification-based guidance a key away) adds the identified track's
law (track_guidance.py, Rajagopalan 1991, 5.4) going forwards: every leading frame feeds the
identification, and the feed-forward law steers instead of the law `cameras` chose once it
can: under feed_forward.form chord (the default) once the window has placed track under the
rear caster, under the conic's forms once the identification has converged; before that, in
reverse, and (the conic's forms) after the fitter restarts on a new primitive of the route,
that law steers. A hand-back carries the angle over: the PI law's integral is set to give the
angle the feed-forward law last gave, so the caster does not jump. With the tape out of the
leading window while following, the truck keeps to the identified track for
identification.gap_distance before the stop.

Frames of one instant: the world renders both cameras in the same step and stamps them alike,
but they arrive one after the other, in either order. A leading frame is steered from at once
when the trailing frame of its instant is already in; otherwise it waits for it. A leading frame
still waiting when the next one comes is steered from alone (its trailing frame never came).
"""

from dataclasses import dataclass, replace

import numpy as np

from agv_nodes.route_following.camera_guidance import (
    ImageAnalyser,
    Measurement,
    Validity,
)
from agv_nodes.route_following.chapter9 import steering_law
from agv_nodes.route_following.dual_camera import DualCameraGuidance
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.route_following.track_guidance import TrackGuidance

# Frames this close in time are one instant: the node stamps each with its arrival, and the two
# of one world step arrive within a sample or two (3 ms apiece); frames come 40-60 ms apart
# (Rajagopalan 1991, 7.5.1.6), so half the shortest spacing still tells instants apart.
SAME_INSTANT = 0.02  # s
SEEN = (Validity.NORMAL, Validity.WIDE)  # a window with the tape in it


@dataclass
class View:
    """What the cameras showed at one instant, for the camera mode to steer by."""

    lead: Measurement  # the leading camera, in the frame of travel
    frame: np.ndarray  # the leading camera's frame (branch edges are measured on it)
    trail: Measurement | None  # the trailing camera of the same instant (cameras = both)
    time: float  # s


class CameraLaw:
    """See the module docstring: frames in, caster angle and wheel speeds out."""

    def __init__(self, params: RouteParams) -> None:
        self.p = params
        self.cameras = params.cameras
        self.analysers = {name: ImageAnalyser(params.image) for name in ('front', 'rear')}
        self.single = steering_law(params.steering, params.turning.camera_ahead,
                                   params.chapter9)  # CameraSteering with chapter9 off
        self.dual = DualCameraGuidance(params.dual, params.steering, params.turning)
        self.dual.reference_point = params.chapter9.reference_point  # 9.6 (0: the front end)
        # Always there: its pose follows the odometry, so a later leg can feed it or drive the
        # track it identified (dead reckoning, App. F.9); a leg's law says whether it steers.
        self.track = TrackGuidance(params)
        self.feed_forward = params.camera_law == 'feed_forward'
        self.direction = 1
        self.law = 'lead'  # the law of the last frame: lead, dual, feed_forward or bridge
        self._waiting: tuple[np.ndarray, Measurement, float] | None = None  # a lead frame
        self._trail: tuple[Measurement, float] | None = None  # the latest trailing reading
        self._trail_seen = False  # the trailing window has shown the tape since the start
        self._last_time: float | None = None

    @property
    def lead_camera(self) -> str:
        """Return the camera facing along travel."""
        return 'front' if self.direction == 1 else 'rear'

    def start(self, direction: int, law: str | None = None) -> None:
        """Start from rest on a tape (a new leg, or a branch after a spin): the laws afresh.

        `law`: the new leg's camera_law (feedback, feed_forward; default or None: the
        parameter's); a branch taken after a spin keeps the leg's.
        """
        if law is not None:
            self.feed_forward = (law if law != 'default' else self.p.camera_law) == 'feed_forward'
        self.direction = direction
        self.single.integral, self.single.absent = 0.0, 0
        self.single.predictor.reset()
        self.dual.direction = direction
        self.dual.reset()
        for analyser in self.analysers.values():
            analyser.forget_track()
        self._share_width()
        self._waiting = self._trail = None
        self._trail_seen = False
        self.track.reset()  # the feedback law starts each leg and branch
        self.law = 'lead'

    def odometry(self, d_left: float, d_right: float) -> None:
        """Take one wheel_odometry record's travel of each wheel, m (the identified track's)."""
        self.track.odometry(d_left, d_right)

    def take(self, frame: np.ndarray, now: float, camera: str) -> list[View]:
        """Take one camera's frame; return the instants now ready to steer by, oldest first."""
        if camera not in self.analysers:
            raise ValueError(f'camera must be front or rear, not {camera!r}')
        if camera != self.lead_camera:
            if self.cameras == 'both':
                self._share_width()
                self._trail = (self.analysers[camera].analyse(frame), now)
                return self._pair()
            return []  # the lead law never looks at it
        m = self.analysers[camera].analyse(frame)
        if self.cameras == 'lead':
            return [View(m, frame, None, now)]
        ready = []
        if self._waiting is not None:  # its trailing frame never came
            ready.append(View(self._waiting[1], self._waiting[0], None, self._waiting[2]))
        self._waiting = (frame, m, now)
        return ready + self._pair()

    def _share_width(self) -> None:
        """Give a camera that has not learnt the tape's normal width the other's.

        An analyser learns it from its first frame with the tape (normal_width 0); a trailing
        window that first meets the tape at a slant, half in view, would learn a narrow one and
        take the plain tape for a road sign. Both cameras look at the same tape.
        """
        lead = self.analysers[self.lead_camera]
        for analyser in self.analysers.values():
            if not analyser.normal_width:
                analyser.normal_width = lead.normal_width or max(
                    a.normal_width for a in self.analysers.values())

    def _pair(self) -> list[View]:
        if self._waiting is None or self._trail is None:
            return []
        frame, lead, t_lead = self._waiting
        trail, t_trail = self._trail
        if abs(t_lead - t_trail) > SAME_INSTANT:
            return []
        self._waiting = self._trail = None
        return [View(lead, frame, trail, t_lead)]

    def steer(self, view: View, speed: float, bridge: bool = False) -> float | None:
        """Return the caster angle in the frame of travel (rad), or None: stop, no track.

        None after absent_frames leading frames without the tape (Rajagopalan 1991, 4.3); a
        saturated leading frame keeps the last angle. `bridge`: the truck is following plain
        tape (no sign, no manoeuvre), so camera_law feed_forward may carry it across a gap.
        """
        dt = 0.05 if self._last_time is None else max(view.time - self._last_time, 1e-3)
        self._last_time = view.time
        if self.feed_forward and self.direction == 1:
            if view.lead.validity is Validity.ABSENT and bridge and self.track.ready:
                self.law = 'bridge'
                return self.track.bridge(dt)  # None past gap_distance: the motor-off stop
            normal = self.analysers[self.lead_camera].normal_width
            theta = self.track.steer(view.lead, dt, normal)
            if theta is not None:
                self.law = 'feed_forward'
                self.single.absent = 0
                return theta
            if self.law in ('feed_forward', 'bridge'):
                self._hand_back(speed)
        return self._feedback(view, dt, speed)

    def _hand_back(self, speed: float) -> None:
        """Start the feedback law from the feed-forward law's last angle (see the docstring)."""
        theta, single, p = self.track.law.theta_s, self.single, self.single.p
        single.theta_s, single.absent = theta, 0
        self.dual.reset()
        if p.law == 'pi' and p.gain_i > 0 and self.track.measured is not None:
            eps_d, eps_theta = self.track.measured
            gain_d = p.gain_d  # as CameraSteering.update schedules it
            if p.schedule_speed > 0 and speed > p.schedule_speed:
                gain_d *= p.schedule_speed / speed
            single.integral = (theta - p.gain_theta * eps_theta - gain_d * eps_d) / p.gain_i

    def _feedback(self, view: View, dt: float, speed: float) -> float | None:
        """Steer by the law `cameras` chose: the leading camera's P / PI or the dual law."""
        trail = view.trail
        if trail is not None and trail.validity is Validity.WIDE:
            # A road sign under the trailing window: its patch and branches shift the fit by
            # centimetres, and the dual law's G3 / G5 terms would steer the front off the tape
            # for them. Its last plain reading stands, as for a saturated frame (6.3.11).
            trail = replace(trail, validity=Validity.SATURATED)
        if trail is not None and trail.validity is Validity.NORMAL:
            self._trail_seen = True
        if view.lead.validity in SEEN and trail is not None and self._trail_seen \
                and trail.validity is not Validity.ABSENT:
            front, rear = (view.lead, trail) if self.direction == 1 else (trail, view.lead)
            theta = self.dual.update(front, rear, dt, self.direction, speed)
            if theta is not None:
                self.law = 'dual'
                self.single.theta_s, self.single.absent = theta, 0
                return theta
        if trail is not None and trail.validity is Validity.ABSENT:
            self._trail_seen = False  # the dual law takes up again from a fresh reading
            self.dual.reset()
        self.law = 'lead'
        return self.single.update(view.lead, dt, speed)

    def wheel_speeds(self, speed: float, theta: float) -> tuple[float, float]:
        """Return (left, right) rim speeds, m/s, + = forwards (see the module docstring).

        `speed` >= 0 is the cruise along travel, `theta` the caster angle in the frame of travel.
        """
        return self.dual.wheel_speeds(speed, theta, self.direction)
