"""Both caster contacts along the reconstructed track: the chord law (ours, not the thesis's).

The feed-forward law of Eq. 5.89-5.91 (feed_forward.py) steers by the osculating circle of
one identified conic. Where the track changes its shape, a straight running into a curve, the
conic fitted is the old shape until the window has seen enough of the new one; the law hands
back to the feedback law, which holds the *window* on the tape, and the casters cut the
curve's start by 40-50 mm (bench/results/identification_closed_loop.md).

The track points themselves (each plain frame's P placed by odometry, Eq. 5.30-5.31:
track_guidance.py) are the track as far as the window, L_c ahead of the axle and so
L_c - L_a beyond the front caster. Both caster contacts are on the track when the body is a
chord of it 2 L_a long; the axle centre O is the chord's midpoint and, on a differential
drive, moves along the body. Holding the body on the chord is then path following with the
chord's own turning as the feed-forward, and it needs no model of the track's shape:

- the rear contact's foot on the track (arc position a_r) and the point ahead of it where
  the chord is 2 L_a long give the chord's heading psi_c and midpoint M;
- e_y, O's offset from M across the chord (+ left), and e_psi, the body's heading from psi_c;
- kappa_ff, the chord's turn per metre of M's travel between the chord at a_r + lead and at
  a_r + lead + STEP: `lead` (speed x chord_lead_time) looks past the frame's and the drive's
  delays;
- O is asked for the curvature kappa = kappa_ff - k_y e_y - k_psi e_psi, which the caster
  angle gives by Eq. 5.10-5.11: tan(theta_s) = L_ae(theta_s) kappa.

Per metre travelled the errors then obey e_y'' + k_psi e_y' + k_y e_y = 0 (small angles): the
gains set a loop in distance, the same at every speed. On a circle of radius R the chord's
midpoint runs R - sqrt(R^2 - L_a^2) inside it (16 mm on R = 2.95 m), the casters' criterion
of Fig. 5.7c reached without the criterion's formula. ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from agv_nodes.track_geometry.feed_forward import Geometry, effective_wheelbase
from agv_nodes.track_geometry.settings import FeedForwardParams

STEP = 0.1  # m of the chord's travel its turn is measured over
BEHIND = 0.1  # m of track wanted behind the rear contact before the law steers


@dataclass(frozen=True)
class Chord:
    """The chord the body should lie on: heading (rad), midpoint (m), turn per metre (1/m)."""

    heading: float
    x: float
    y: float
    kappa: float


class TrackPolyline:
    """Points of the track in order of travel, with arc lengths; feet and chords on it."""

    def __init__(self, points: np.ndarray) -> None:
        self.points = points
        steps = np.hypot(*np.diff(points, axis=0).T)
        self.arc = np.concatenate(([0.0], np.cumsum(steps)))

    @property
    def length(self) -> float:
        """Return the polyline's length, m."""
        return float(self.arc[-1])

    def at(self, a: float) -> np.ndarray:
        """Return the point at arc length `a` (clamped to the ends)."""
        a = min(max(a, 0.0), self.length)
        k = min(int(np.searchsorted(self.arc, a, side='right')) - 1, len(self.arc) - 2)
        span = self.arc[k + 1] - self.arc[k]
        t = 0.0 if span <= 0.0 else (a - self.arc[k]) / span
        return self.points[k] + t * (self.points[k + 1] - self.points[k])

    def foot(self, x: float, y: float) -> float:
        """Return the arc length of the point of the polyline nearest (x, y)."""
        p, q = self.points[:-1], self.points[1:]
        d = q - p
        lengths = np.einsum('ij,ij->i', d, d)
        t = np.clip(np.einsum('ij,ij->i', np.array([x, y]) - p, d)
                    / np.where(lengths > 0.0, lengths, 1.0), 0.0, 1.0)
        near = p + t[:, None] * d
        k = int(np.argmin(np.hypot(near[:, 0] - x, near[:, 1] - y)))
        return float(self.arc[k] + t[k] * math.sqrt(lengths[k]))

    def chord_end(self, a: float, length: float) -> float | None:
        """Return the arc length ahead of `a` where the chord from `a` is `length` long."""
        start = self.at(a)
        k = int(np.searchsorted(self.arc, a, side='right'))
        far = np.hypot(*(self.points[k:] - start).T)
        beyond = np.nonzero(far >= length)[0]
        if not len(beyond):
            return None  # the track is not known that far ahead
        j = k + int(beyond[0])
        p, q = self.points[j - 1], self.points[j]
        # |p + t (q - p) - start| = length on the segment reaching past it
        d, w = q - p, p - start
        aa, bb, cc = d @ d, 2.0 * (d @ w), w @ w - length * length
        t = (-bb + math.sqrt(max(bb * bb - 4.0 * aa * cc, 0.0))) / (2.0 * aa)
        return float(self.arc[j - 1] + t * (self.arc[j] - self.arc[j - 1]))

    def chord(self, a: float, length: float) -> tuple[float, np.ndarray] | None:
        """Return (heading, midpoint) of the chord `length` long from arc length `a` on."""
        end = self.chord_end(a, length)
        if end is None:
            return None
        p, q = self.at(a), self.at(end)
        return math.atan2(q[1] - p[1], q[0] - p[0]), 0.5 * (p + q)


class ChordSteering:
    """See the module docstring: track points and pose in, caster angle out."""

    def __init__(self, geometry: Geometry, params: FeedForwardParams | None = None) -> None:
        self.g = geometry
        self.p = params or FeedForwardParams()
        self.errors = (0.0, 0.0)  # (e_y m, e_psi rad) the law last steered by
        self.chord: Chord | None = None

    def target(self, track: TrackPolyline, x: float, y: float, heading: float,
               speed: float) -> Chord | None:
        """Return the chord the body should lie on now, or None: too little track known."""
        span = 2.0 * self.g.caster_distance
        rear = self.g.caster_distance
        a_r = track.foot(x - rear * math.cos(heading), y - rear * math.sin(heading))
        if a_r < BEHIND:
            return None  # the rear contact is not yet over tape the window has seen
        now = track.chord(a_r, span)
        lead = a_r + abs(speed) * self.p.chord_lead_time
        ahead = track.chord(lead, span)
        further = track.chord(lead + STEP, span)
        if now is None or ahead is None or further is None:
            return None
        moved = float(np.hypot(*(further[1] - ahead[1])))
        turn = math.remainder(further[0] - ahead[0], 2.0 * math.pi)
        kappa = turn / moved if moved > 1e-6 else 0.0
        return Chord(now[0], float(now[1][0]), float(now[1][1]), kappa)

    def steer(self, track: TrackPolyline, x: float, y: float, heading: float,
              speed: float) -> float | None:
        """Return the caster angle (rad, + left) that brings the body onto the chord, or None."""
        chord = self.target(track, x, y, heading, speed)
        self.chord = chord
        if chord is None:
            return None
        c, s = math.cos(chord.heading), math.sin(chord.heading)
        e_y = -s * (x - chord.x) + c * (y - chord.y)
        e_psi = math.remainder(heading - chord.heading, 2.0 * math.pi)
        self.errors = (e_y, e_psi)
        kappa = chord.kappa - self.p.chord_gain_y * e_y - self.p.chord_gain_heading * e_psi
        theta = math.atan(self.g.caster_distance * kappa)
        for _ in range(3):  # L_ae depends on the angle through the trail only
            theta = math.atan(effective_wheelbase(theta, self.g.caster_distance,
                                                  self.g.caster_trail) * kappa)
        return max(-self.g.max_angle, min(self.g.max_angle, theta))
