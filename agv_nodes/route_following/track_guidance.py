"""Camera guidance by the identified track: feed-forward steering (Rajagopalan 1991, 5.4).

ROS-free. The thesis's scheme (5.4.6), run closed loop as the thesis could not (its 80286 was
too slow, 7.6):

1. The truck's pose in an odometry frame from the wheel_odometry counters (PoseIntegrator,
   Eq. 5.38), one integration step per record. Each record's travel is what counts: its
   period only scales the speeds the trapezoid averages, so a constant one keeps the
   records' arrival jitter over DDS out of the pose, and a spin or a wait between frames is
   integrated as finely as the cruise.
2. Every leading frame with the plain tape in view places the track point P under the window
   (track_point, Eq. 5.30-5.31) and gives it to the TrackFitter (5.4.2). A frame that shows
   part of a road sign or a tape's end moves P by millimetres but turns the line fitted
   across the window by up to a radian, and the conic model, parameterised by the track's
   heading, turns 0.1 rad into 0.3 m. So no sample comes from a frame that is wide, has a
   branch at an edge, averages PLAIN_WIDTH times the tape's normal width (the first rows of a
   sign's patch), or has rows without the tape (an end across the window). Fewer rows of a
   patch or a branch pass those tests yet read the heading 0.06-0.12 rad off: while the
   identification is ready a sample more than GATE_HEADING off the identified curve's
   heading is left out, unless GATE_SAMPLES in a row are (then the track has changed: a curve
   begins). Nor does a frame before O has moved SPACING on give one (a truck waiting at a
   junction would pile samples onto one point).
3. Once the fitter's own test passes (TrackFitter.ready), P is carried one frame's travel on
   along the identified curve and the osculating circle taken there (5.4.4.1); the
   FeedForwardSteering law (Eq. 5.89-5.91, its positional form) steers by the
   circle's radius and the side of its centre, on the offsets measured on plain tape and on
   those the window would read of the identified curve where a frame gave no sample. Until
   then the feedback law steers (camera_law.py), as it does in reverse. That law held the
   window on the tape, so on taking over the criterion's eps_dd comes in over
   feed_forward.ramp_distance.
   Under feed_forward.form chord (the default) the chord law steers instead, from the
   first frame the plain frames' points reach back past the rear caster (chord_law.py:
   both casters on the chord of those points, no fit needed, so no hand-back where a curve
   begins); the conic's law steers only where the chord law cannot (a road sign, whose
   frames place no points), and the circle is still taken, for the picture.
4. A leading window without the tape, while following: the truck keeps going along the
   identified curve (2.3.3; App. F.5: no stop in identification mode). The offsets the window
   would read are taken from the pose and the curve, up to identification.gap_distance of
   travel since the tape was last seen; then None, the motor-off stop.
5. Dead reckoning (App. F.9, `reckon`): no camera at all; the truck goes along a given curve
   (a stored trajectory placed at its pose, or the track identified last), steered every
   call by the offsets the window would read of it, as across a gap, for as long as the leg
   lasts. The criterion's offsets apply from the start: no feedback law held the window.

The curve is the fitter's implicit conic f(x, y) = 0, signed so that (f_y, -f_x) points along
travel (TrackFitter.implicit): a line, the polynomial's parabola or the conic's ellipse alike.
"""

from __future__ import annotations

from collections import deque
import math

import numpy as np

from agv_nodes.route_following.camera_guidance import Measurement, Validity
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.track_geometry.chord_law import ChordSteering, TrackPolyline
from agv_nodes.track_geometry.criteria import centre_side
from agv_nodes.track_geometry.feed_forward import FeedForwardSteering, Geometry
from agv_nodes.track_geometry.fitting import Conic
from agv_nodes.track_geometry.osculating import Circle, osculating_implicit
from agv_nodes.track_geometry.pose import PoseIntegrator, track_point
from agv_nodes.track_geometry.track_fitter import TrackFitter

ODOMETRY_SAMPLE = 0.01  # s: each wheel_odometry record is one integration step (see above)
SPACING = 0.005  # m of O's travel between two track samples at least
# Plain tape reads within 3 % of its normal width (a 0.22 rad slant widens each row 2.4 %).
PLAIN_WIDTH = 1.1
# On plain tape 99 % of frames read the track's heading within 0.017 rad (tape_1991, both
# CONCIC-II models, 0.3-0.9 m/s); a curve of R = 2.95 m leaves its tangent by 0.05 rad in 0.15 m.
GATE_HEADING = 0.05  # rad
GATE_SAMPLES = 5
MARCH_STEP = 0.02  # m: the extrapolation walks the curve in steps this long at most
TRACK_POINTS = 200  # most points in the picture of the identified track
KEPT = 5000  # most samples kept for that picture (memory all: the latest)
PATH_KEPT = 2.0  # m of O's travel: the track points the chord law looks along


def _gradient(conic: Conic, x: float, y: float) -> tuple[float, float, float]:
    """(f, f_x, f_y) of the conic at (x, y)."""
    A, B, C, D, E, F = conic
    return (A * x * x + B * x * y + C * y * y + D * x + E * y + F,
            2.0 * A * x + B * y + D, B * x + 2.0 * C * y + E)


def foot(conic: Conic, x: float, y: float, iterations: int = 4) -> tuple[float, float] | None:
    """Return the point of the curve nearest (x, y) by Newton steps along the gradient.

    None where the gradient vanishes (the centre of an ellipse): no nearest point to find.
    """
    for _ in range(iterations):
        f, fx, fy = _gradient(conic, x, y)
        g2 = fx * fx + fy * fy
        if not g2 > 0.0 or not math.isfinite(g2):
            return None
        x, y = x - f * fx / g2, y - f * fy / g2
    return x, y


def tangent(conic: Conic, x: float, y: float) -> tuple[float, float] | None:
    """Return the unit tangent along travel, (f_y, -f_x) normalised; None without one."""
    _f, fx, fy = _gradient(conic, x, y)
    g = math.hypot(fx, fy)
    return (fy / g, -fx / g) if g > 0.0 and math.isfinite(g) else None


def march(conic: Conic, x: float, y: float, distance: float) -> tuple[float, float] | None:
    """Walk `distance` m along the curve from its point nearest (x, y), in the travel's sense."""
    at = foot(conic, x, y)
    steps = max(1, math.ceil(abs(distance) / MARCH_STEP))
    for _ in range(steps):
        if at is None or (t := tangent(conic, *at)) is None:
            return None
        at = foot(conic, at[0] + t[0] * distance / steps, at[1] + t[1] * distance / steps)
    return at


def crossing(conic: Conic, x: float, y: float, nx: float, ny: float) -> float | None:
    """Return t of the curve's crossing nearest (x, y) on the line (x, y) + t (nx, ny).

    f along the line is a quadratic in t: a t^2 + b t + c with c = f, b = grad f . n. None when
    the line misses the curve.
    """
    A, B, C, *_ = conic
    c, fx, fy = _gradient(conic, x, y)
    a, b = A * nx * nx + B * nx * ny + C * ny * ny, fx * nx + fy * ny
    if abs(a) <= 1e-12 * (abs(b) + abs(c)):
        return -c / b if b != 0.0 else None
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return None
    root = math.sqrt(disc)
    return min((-b + root) / (2.0 * a), (-b - root) / (2.0 * a), key=abs)


class TrackGuidance:
    """See the module docstring: odometry and leading frames in, caster angle out."""

    def __init__(self, params: RouteParams) -> None:
        s, ident = params.steering, params.identification
        self.ident = ident
        self.rows = len(params.image.rows) or 64  # rows the analyser reads
        self.geometry = Geometry(camera_ahead=params.turning.camera_ahead,
                                 caster_distance=s.caster_distance, caster_trail=s.caster_trail,
                                 max_angle=s.max_angle)
        self.pose = PoseIntegrator(s.wheel_span, ident.rule, ident.left_scale)
        self.fitter = TrackFitter(ident)
        self.law = FeedForwardSteering(params.feed_forward, self.geometry)
        self.chord = ChordSteering(self.geometry, params.feed_forward) \
            if params.feed_forward.form == 'chord' else None
        # Every plain frame's P (s, x, y), heading gate or not: the chord law's track
        self._path: deque[tuple[float, float, float]] = deque()
        self.circle: Circle | None = None  # osculating, where the window looks next
        self.measured: tuple[float, float] | None = None  # the last plain frame's offsets
        self.bridged = 0.0  # m driven with the tape out of the window (the latest gap)
        self._samples: deque[tuple[float, float, float]] = deque(maxlen=KEPT)  # s, x, y
        self._seen_at: float | None = None  # O's distance when the tape was last in view
        self._frame_at: float | None = None  # O's distance at the last leading frame
        self._frame_travel = 0.0  # m O went between the last two leading frames
        self._rejected = 0  # samples in a row left out by the heading gate
        self._took_over: float | None = None  # O's distance when the law last began to steer
        self.offsets = (0.0, 0.0)  # the (eps_d, eps_theta) the law last steered by

    @property
    def ready(self) -> bool:
        """Whether the identification has converged (TrackFitter.ready)."""
        return self.fitter.ready

    def reset(self) -> None:
        """Identify afresh: a new leg, a branch taken after a spin, a change of direction.

        The odometry frame stays: the pose goes on from where it is.
        """
        self.fitter.reset()
        self.law.reset()
        self.circle, self.measured, self.bridged = None, None, 0.0
        self._samples.clear()
        self._path.clear()
        self._seen_at = self._frame_at = self._took_over = None
        self._rejected = 0

    def odometry(self, d_left: float, d_right: float) -> None:
        """Take one wheel_odometry record's travel of each wheel, m (+ forwards)."""
        self.pose.update_travel(d_left, d_right, ODOMETRY_SAMPLE)

    def _frame(self) -> None:
        distance = self.pose.distance
        if self._frame_at is not None:
            self._frame_travel = max(distance - self._frame_at, 0.0)
        self._frame_at = distance

    def steer(self, m: Measurement, dt: float, normal_width: float = 0.0) -> float | None:
        """Return the caster angle for this leading frame, or None: the feedback law steers.

        Every frame with the plain tape in view goes to the identification (`normal_width`:
        the tape's, px, as the image analyser learnt it; 0: not known, no test). Once it is
        ready the law steers by the offsets measured on plain tape, and by those the window
        would read of the identified track where a road sign or a tape's end disturbs the
        frame (its fit reads the track's heading up to a radian off); a saturated frame keeps
        the last angle (Rajagopalan 1991, 6.3.11).
        """
        self._frame()
        if m.validity is Validity.SATURATED:
            return self.law.theta_s if self.measured is not None and self.ready else None
        if m.validity is Validity.ABSENT:
            return None
        self._seen_at, self.bridged = self.pose.distance, 0.0
        plain = m.validity is Validity.NORMAL and m.rows_used >= self.rows \
            and not (m.left_edge or m.right_edge) \
            and (not normal_width or m.width_px < PLAIN_WIDTH * normal_width)
        x, y, heading = self.pose.pose
        px, py, theta_p = track_point(x, y, heading, self.geometry.camera_ahead, m.eps_d,
                                      m.eps_theta)
        if plain:
            s = self.pose.distance
            if (not self._samples or s - self._samples[-1][0] >= SPACING) \
                    and self._takes(px, py, theta_p):
                self.fitter.add(px, py, theta_p, s)
                self._samples.append((s, px, py))
            self.measured = (m.eps_d, m.eps_theta)
            if not self._path or s - self._path[-1][0] >= SPACING:
                self._path.append((s, px, py))
                while s - self._path[0][0] > PATH_KEPT:
                    self._path.popleft()
        if self.chord is not None and (theta := self._steer_chord(dt)) is not None:
            if plain and self.ready:  # the circle the identification gives, to be looked at
                self.circle = self._circle_ahead(px, py) or self.circle
            return theta
        if not self.ready:
            self._took_over = None  # the feedback law steers: the next take-over ramps again
            return None
        if plain:
            return self._steer(m.eps_d, m.eps_theta, px, py, dt)
        return self._steer_on_track(dt)

    def _steer_chord(self, dt: float) -> float | None:
        """Return the chord law's caster angle, or None: too little track placed yet.

        Once it steers, the conic's law, should it take over (across a road sign, which gives
        no track points), aims at its criterion in full: the casters are already on the tape.
        """
        if len(self._path) < 2:
            return None
        x, y, heading = self.pose.pose
        speed = self._frame_travel / dt if dt > 0.0 else 0.0
        track = TrackPolyline(np.array([(px, py) for _s, px, py in self._path]))
        theta = self.chord.steer(track, x, y, heading, speed)
        if theta is not None:
            self.law.theta_s = theta  # a hand-back to the feedback law starts from it
            self._took_over = self.pose.distance - self.law.p.ramp_distance
        return theta

    def _takes(self, px: float, py: float, theta_p: float) -> bool:
        """Whether the sample's heading agrees with the identified track's (see GATE_HEADING)."""
        conic = self.fitter.implicit() if self.ready else None
        at = None if conic is None else foot(conic, px, py)
        along = None if at is None else tangent(conic, *at)
        if along is None or abs(math.remainder(theta_p - math.atan2(along[1], along[0]),
                                               2.0 * math.pi)) <= GATE_HEADING:
            self._rejected = 0
            return True
        self._rejected += 1
        return self._rejected > GATE_SAMPLES

    def bridge(self, dt: float) -> float | None:
        """Return the caster angle across a gap in the tape, None once it is too long."""
        self._frame()
        if not self.ready or self._seen_at is None:
            return None
        self.bridged = self.pose.distance - self._seen_at
        if self.bridged > self.ident.gap_distance:
            return None
        return self._steer_on_track(dt)

    def reckon(self, conic: Conic, dt: float) -> float | None:
        """Return the caster angle along `conic` by odometry alone; None where it cannot go on.

        `conic`: in the odometry frame, its tangent (f_y, -f_x) along travel (dead_reckoning.py).
        """
        self._frame()
        if self._took_over is None:  # the criterion in full from the start (see 5. above)
            self._took_over = self.pose.distance - self.law.p.ramp_distance
        return self._steer_on_track(dt, conic)

    def _steer_on_track(self, dt: float, conic: Conic | None = None) -> float | None:
        """Steer by the offsets the window would read of the identified track (or of `conic`).

        Where the line across the window meets the curve, and the curve's heading there.
        """
        conic = self.fitter.implicit() if conic is None else conic
        if conic is None:
            return None
        x, y, heading = self.pose.pose
        c, s = math.cos(heading), math.sin(heading)
        bx, by = x + self.geometry.camera_ahead * c, y + self.geometry.camera_ahead * s
        t = crossing(conic, bx, by, -s, c)
        if t is None or (along := tangent(conic, bx - t * s, by + t * c)) is None:
            return None
        eps_theta = math.remainder(math.atan2(along[1], along[0]) - heading, 2.0 * math.pi)
        return self._steer(t, eps_theta, bx - t * s, by + t * c, dt, conic)

    def _circle_ahead(self, px: float, py: float, conic: Conic | None = None) -> Circle | None:
        """Return the osculating circle one frame's travel on from P along the conic."""
        conic = self.fitter.implicit() if conic is None else conic
        ahead = None if conic is None else march(conic, px, py, self._frame_travel)
        if ahead is None or (along := tangent(conic, *ahead)) is None:
            return None
        return osculating_implicit(conic, *ahead, heading=math.atan2(along[1], along[0]))

    def _steer(self, eps_d: float, eps_theta: float, px: float, py: float,
               dt: float, conic: Conic | None = None) -> float | None:
        """Steer by the osculating circle one frame's travel on from P."""
        circle = self._circle_ahead(px, py, conic)
        if circle is None:
            return None
        self.circle = circle
        x, y, heading = self.pose.pose
        side = 0 if circle.straight else centre_side(circle.h, circle.k, x, y, heading)
        if self._took_over is None:
            self._took_over = self.pose.distance
        ramp = self.law.p.ramp_distance
        share = min(1.0, (self.pose.distance - self._took_over) / ramp) if ramp > 0 else 1.0
        self.offsets = (eps_d, eps_theta)
        return self.law.update(eps_d, eps_theta, circle.radius, side, dt, share)

    def track(self) -> list[tuple[float, float]]:
        """Return the identified track in the odometry frame: the fitted curve at the samples.

        The points of the curve nearest the samples the fit holds (its window, or all since
        the start or the last reset), at most TRACK_POINTS of them; none before a fit.
        """
        conic = self.fitter.implicit()
        if conic is None or not self._samples:
            return []
        latest = self._samples[-1][0]
        span = self.fitter.travelled  # since the start or the fitter's own last reset
        if self.ident.memory == 'window':
            span = min(span, self.ident.window)
        kept = [(x, y) for s, x, y in self._samples if latest - s <= span]
        stride = max(1, math.ceil(len(kept) / TRACK_POINTS))
        points = [foot(conic, x, y) for x, y in kept[::stride]]
        return [p for p in points if p is not None]
