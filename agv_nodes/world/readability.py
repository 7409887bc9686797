"""Can the truck read a marker card? The world's sensor model and the position sensor decide.

The layout check (agv_nodes/world/layout_check.py) records, for each card, the lens poses of the
truck's worst pass over it as driven. `reads` replays those poses through the same optics and
electronics the simulated world uses (agv_nodes.world.marker_sensor.MarkerSensorModel, its
calibration, noise and ride height) into the position sensor's SAMPLE / THRESH / DECODE
(agv_nodes.position_sensor.core, default processing), once per seed: the card is readable when
every seed's pass reports its identity (a location marker's number; the stop-marker centre,
EDIM, for a stop card, as navigation sees it at cruise). So the check refuses exactly the cards
the simulated truck cannot read, whatever limits the thesis gives for the sensor on its own
(Baker 1983, 7.1.4: 280-320 mm, about +-10 degrees).

`margin` measures how far a readable card is from being unreadable (and an unreadable one from
being read): the card turned further about its vertical axis, or moved along its normal, until
the verdict changes, found by bisection; a card within `MARGINAL_DEG` or `MARGINAL_M` of the
change is marginal.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
import math
import random

from agv_nodes.markers import EDIM
from agv_nodes.position_sensor.core import PositionSensorCore
from agv_nodes.world.layout import Marker
from agv_nodes.world.marker_sensor import MarkerSensorModel
from agv_nodes.world.settings import WorldParams

SEEDS = (0, 1, 2)  # noise seeds a pass is replayed with: readable only if all read it
MARGINAL_DEG = 2.0  # a card this close (degrees of turn) to the change of verdict is marginal
MARGINAL_M = 0.005  # likewise, m along its normal
TURN_SPAN = 30.0  # degrees searched either way for the change of verdict
SHIFT_SPAN = 0.06  # m searched either way along the normal
TURN_STEP, SHIFT_STEP = 0.1, 0.0005  # bisection ends when the bracket is this narrow

Pose = tuple[tuple[float, float], float]  # (lens x, y), heading


def expected_identity(marker: Marker) -> int | None:
    """Return the identity the navigating table reports for `marker` (None: none is read)."""
    if marker.kind == 'location':
        return marker.identity
    if marker.kind == 'stop':
        return EDIM
    return None


def reads(marker: Marker, poses: list[Pose], world: WorldParams,
          seeds: tuple[int, ...] = SEEDS) -> bool:
    """Return True when every seed's replay of `poses` (one per world sample) reads `marker`."""
    want = expected_identity(marker)
    if want is None:
        return True
    height = world.electruk.payload / 1000.0 * world.ride_height_per_tonne
    dt = 1.0 / world.sample_rate
    for seed in seeds:
        sensor = MarkerSensorModel(world.sensor, random.Random(seed))
        decoder = PositionSensorCore()
        found = False
        for k, (lens, heading) in enumerate(poses):
            lit, dark = sensor.snapshot(lens, heading, [marker], height)
            out = decoder.sample(lit, dark, k * dt)
            if out is not None and out['position_sensor_status']['identity'] == want:
                found = True
                break
        if not found:
            return False
    return True


def turned(marker: Marker, degrees: float) -> Marker:
    """Return `marker` turned about its vertical axis by `degrees` (+ = counter-clockwise)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    (ax, ay), (nx, ny) = marker.along, marker.normal
    return replace(marker, along=(c * ax - s * ay, s * ax + c * ay),
                   normal=(c * nx - s * ny, s * nx + c * ny), yaw=marker.yaw + a)


def shifted(marker: Marker, metres: float) -> Marker:
    """Return `marker` moved `metres` away from the path along its normal."""
    (cx, cy), (nx, ny) = marker.centre, marker.normal
    return replace(marker, centre=(cx - nx * metres, cy - ny * metres),
                   standoff=marker.standoff + metres)


@dataclass
class Readability:
    """A card's verdict on its worst pass, and how near it is to the other verdict.

    `turn` and `shift`: for a readable card, how far it may turn (degrees, away from square) or
    move (m, away from the lens's focus) and still be read, each measured only up to
    MARGINAL_DEG / MARGINAL_M (None: at least that); for an unreadable one, how far it must turn
    back or move toward the focus to be read (None: not within TURN_SPAN / SHIFT_SPAN).
    """

    readable: bool
    turn: float | None
    shift: float | None
    outward: bool  # the pass's standoff is beyond the focus: moving out is the worse way

    @property
    def marginal(self) -> bool:
        """Return True for a readable card within MARGINAL_DEG or MARGINAL_M of unreadable."""
        return self.readable and (self.turn is not None or self.shift is not None)

    def margin(self) -> str:
        """Return the margin in words ('' for a readable card that is not marginal)."""
        worse, better = ('out', 'in') if self.outward else ('in', 'out')
        parts = []
        if self.readable:
            if self.turn is not None:
                parts.append(f'unread if turned {self.turn:.1f} deg more')
            if self.shift is not None:
                parts.append(f'unread if moved {self.shift * 1000:.1f} mm {worse}')
            return ', '.join(parts)
        if self.turn is not None:
            parts.append(f'read if turned {self.turn:.1f} deg toward square')
        if self.shift is not None:
            parts.append(f'read if moved {self.shift * 1000:.1f} mm {better}')
        return ' or '.join(parts) or (f'not read within {TURN_SPAN:.0f} deg of turn or '
                                      f'{SHIFT_SPAN * 1000:.0f} mm of move')


def _edge(verdict: Callable[[float], bool], readable: bool, span: float,
          step: float) -> float | None:
    """Smallest x in (0, span] where verdict(x) != readable, by bisection (None: none there).

    The verdict is taken to change once over the span (one edge of the readable region).
    """
    if verdict(span) == readable:
        return None
    lo, hi = 0.0, span
    while hi - lo > step:
        mid = (lo + hi) / 2.0
        if verdict(mid) == readable:
            lo = mid
        else:
            hi = mid
    return hi


def readability(marker: Marker, poses: list[Pose], world: WorldParams,
                angle: float, standoff: float) -> Readability:
    """Judge `marker` on the pass `poses`, and measure its margin (see the module docstring).

    `angle` (degrees, + = card turned left) and `standoff` (m) are the pass's geometry at the
    card centre: the worse turn is away from square, the worse move away from the lens's
    focus. A readable card's margin is searched only up to the marginal bounds.
    """
    readable = reads(marker, poses, world)
    outward = standoff >= world.sensor.focus
    turn_sign = 1.0 if angle >= 0.0 else -1.0
    shift_sign = 1.0 if outward else -1.0
    if not readable:  # the better way: back toward square, toward the focus
        turn_sign, shift_sign = -turn_sign, -shift_sign
    turn_span = MARGINAL_DEG if readable else min(TURN_SPAN, abs(angle) + TURN_SPAN)
    turn = _edge(lambda x: reads(turned(marker, turn_sign * x), poses, world), readable,
                 turn_span, TURN_STEP)
    shift = _edge(lambda x: reads(shifted(marker, shift_sign * x), poses, world), readable,
                  MARGINAL_M if readable else SHIFT_SPAN, SHIFT_STEP)
    return Readability(readable, turn, shift, outward)
