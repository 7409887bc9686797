"""Which camera steers a leg: front, rear or both in either direction (Rajagopalan 1991, App. F).

The thesis's keys chose the front or the rear camera for guidance in the single camera mode
(App. F.2 item 7) or both (item 8, the dual law of 5.3); App. F.5 offers (f)ront, (r)ear or
(b)oth. A leg's choice comes in route_command `camera` (default: the camera_select parameter):

  auto:  the camera facing along travel leads (camera_law.py), with the law `cameras` chose.
  both:  the dual-camera law (5.3, dual_camera.py) in either direction: camera_law.py already
         pairs the two windows by the frame of travel, front = the one ahead.
  front, rear: that camera alone. When it faces along travel it is the leading camera as ever;
         otherwise it trails: the rear camera driving forwards, the front one in reverse.

A trailing window. Take the frame of travel (x along travel, y to its left). The trailing camera
faces against travel, so its image is the frame of travel turned half a revolution: the tape's
offset from the window centre reads e = -eps_d, its angle (a line's, kept by a half turn)
a = eps_theta. The window centre is L_c behind the axle. Per metre travelled with yaw u (rad/m,
+ = left; u = tan(theta) / L_a, Eq. 5.10) the leading window's offset goes e' = a - L_c u, the
trailing one's e' = a + L_c u, and for both a' = k - u (k the tape's curvature): the lever is
opposite, so u to e is (L_c s - 1) / s^2, a zero in the right half plane at 1 / L_c (1.6 /m).
That is the hard case: steering the trailing window onto the tape by its offset alone (or holding
it there exactly, u = -a / L_c) leaves the heading to diverge as exp(s / L_c). The thesis gives
no analysis of a trailing sensor (its single-camera runs, 7.3, all lead; App. F.2 item 7 only
offers the key). Fed back with its angle it is stable:

    u = G e + H a + (1 + H L_c) k,    G = p^2,  H = 2 p + L_c p^2,

puts both roots of s^2 + (H - L_c G) s + G at -p per metre; on a circle the steady state
u = k, a = -L_c k needs e = 0 (the last term: the window on the tape with no offset). TRAIL_POLE
p = 1 /m, under the zero, keeps the angle gain L_a H = 0.82 rad per rad: the leading camera's
law put through the same geometry (its poles, 1.5 and 5.2 /m) needs 3.7, and in lock step
(kinematic model, 0.47 m/s) rang 60 mm on the straight on each frame's angle noise. The
curvature k is the tape's, measured at the trailing window: the change of its angle plus the
truck's yaw from wheel odometry, per metre, over the last CURVATURE_RUN; never the truck's own
turn, which would feed the law's output back into its input.

Not done for a trailing camera: feed_forward (the identification reads a leading window) and
the junction manoeuvre (branch edges are measured ahead of a leading window); a trailing leg
counts road signs, left and right those of travel, and a turn decision at one stops no_branch.
"""

from collections import deque
from dataclasses import replace
import math

import numpy as np

from agv_nodes.route_following.camera_guidance import Measurement, Validity
from agv_nodes.route_following.camera_law import CameraLaw, View
from agv_nodes.route_following.settings import RouteParams

CHOICES = ('auto', 'front', 'rear', 'both')  # the camera_select parameter's
# The trailing window's curvature is the slope of its tape angle (plus the yaw) over this much
# travel: a frame's angle comes in steps of about 0.03 rad (one column over the 50 mm window),
# 0.1 /m of noise between two frames 0.3 m apart; the least-squares slope over the frames in
# between is steadier, and lags half the run.
CURVATURE_RUN = 0.3  # m
TRAIL_POLE = 1.0  # 1/m: both roots of the trailing loop, per metre travelled (module docstring)


def choose(leg: str, parameter: str) -> str:
    """Return the camera choice of a leg: route_command's `camera`, default the parameter's."""
    choice = parameter if leg in ('default', '') else leg
    if choice not in CHOICES:
        raise ValueError(f'camera must be one of {", ".join(CHOICES)}, not {choice!r}')
    return choice


def steering_camera(choice: str, direction: int) -> str:
    """Return the camera that steers under `choice` going `direction` (+1 forwards)."""
    if choice in ('front', 'rear'):
        return choice
    return 'front' if direction == 1 else 'rear'


def in_travel(m: Measurement) -> Measurement:
    """Return a trailing window's reading in the frame of travel (module docstring)."""
    return replace(m, eps_d=-m.eps_d, left_edge=m.right_edge, right_edge=m.left_edge)


def trailing_yaw(e: float, a: float, kappa: float, l_c: float, pole: float = TRAIL_POLE
                 ) -> float:
    """Return the yaw per metre (rad/m, + = left) that steers a trailing window (docstring)."""
    g, h = pole * pole, 2.0 * pole + l_c * pole * pole
    return g * e + h * a + (1.0 + h * l_c) * kappa


def _slope(points: list[tuple[float, float]]) -> float:
    """Return the least-squares slope of (x, y) points: a frame's angle is read to a column."""
    n = len(points)
    mx = sum(x for x, _ in points) / n
    my = sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    return sum((x - mx) * (y - my) for x, y in points) / sxx if sxx > 0 else 0.0


class SelectedCameraLaw(CameraLaw):
    """CameraLaw with a leg's camera choice: a trailing camera steers by trailing_yaw."""

    def __init__(self, params: RouteParams) -> None:
        super().__init__(params)
        self.choice = choose('default', params.camera_select)
        self._steering = 'front'
        self.kappa = 0.0  # 1/m: the tape's curvature at a trailing window, filtered
        self._run = self._yaw = 0.0  # m and rad travelled since the leg began, frame of travel
        # (run, yaw, tape angle) of the trailing frames with tape over the last CURVATURE_RUN
        self._seen: deque[tuple[float, float, float]] = deque()

    @property
    def lead_camera(self) -> str:
        """Return the camera that steers the leg (the leading one unless a leg chose)."""
        return self._steering

    @property
    def trailing(self) -> bool:
        """Return True when the steering camera faces against travel."""
        return self._steering != ('front' if self.direction == 1 else 'rear')

    def start(self, direction: int, law: str | None = None, camera: str | None = None) -> None:
        """Start as CameraLaw.start; `camera`: a new leg's choice (None: the leg's so far)."""
        if camera is not None:
            self.choice = choose(camera, self.p.camera_select)
        self.direction = direction
        self._steering = steering_camera(self.choice, direction)
        self.cameras = 'both' if self.choice == 'both' else \
            'lead' if self.choice in ('front', 'rear') else self.p.cameras
        super().start(direction, law)
        if self.trailing:
            self.feed_forward = False
        self.kappa, self._run, self._yaw = 0.0, 0.0, 0.0
        self._seen.clear()

    def odometry(self, d_left: float, d_right: float) -> None:
        """Take each wheel's travel, m: the identified track's, and the trailing curvature's."""
        super().odometry(d_left, d_right)
        self._run += self.direction * (d_left + d_right) / 2.0
        self._yaw += (d_right - d_left) / self.p.steering.wheel_span

    def take(self, frame: np.ndarray, now: float, camera: str) -> list[View]:
        """Take one camera's frame; a trailing camera's reading turned into a leading one's."""
        views = super().take(frame, now, camera)
        if not self.trailing:
            return views
        return [replace(v, lead=self._lead(v.lead)) for v in views]

    def _lead(self, m: Measurement) -> Measurement:
        if m.rows_used:
            # The tape's angle in the window turns by k - u per metre (module docstring).
            self._seen.append((self._run, self._yaw, m.eps_theta))
            while len(self._seen) > 2 and self._run - self._seen[1][0] >= CURVATURE_RUN:
                self._seen.popleft()
            if self._run - self._seen[0][0] >= CURVATURE_RUN:
                self.kappa = _slope([(run, angle + yaw) for run, yaw, angle in self._seen])
        return in_travel(m)

    def steer(self, view: View, speed: float, bridge: bool = False) -> float | None:
        """Return the caster angle as CameraLaw.steer; a trailing camera by trailing_yaw."""
        if not self.trailing:
            return super().steer(view, speed, bridge)
        self.law = 'trailing'
        single, p = self.single, self.p.steering
        if view.lead.validity is Validity.ABSENT:
            single.absent += 1  # absent_frames of them: the motor-off stop (4.3)
            return None if single.absent >= p.absent_frames else single.theta_s
        single.absent = 0
        if view.lead.validity is Validity.SATURATED:
            return single.theta_s  # ignore the frame: steer from the previous data
        yaw = trailing_yaw(view.lead.eps_d, view.lead.eps_theta, self.kappa,
                           self.p.turning.camera_ahead)
        theta = math.atan(p.caster_distance * yaw)  # Eq. 5.10 at the caster's own trail
        single.theta_s = max(-p.max_angle, min(p.max_angle, theta))
        return single.theta_s

    def describe(self) -> str:
        """Return the leg's cameras for the notes."""
        if self.choice in ('front', 'rear'):
            return f'{self.choice} camera' + (' trailing' if self.trailing else '')
        return 'both cameras' if self.cameras == 'both' else 'the leading camera'
