"""The pulsed-IR marker sensor: 2 x 4 photodiodes looking sideways at marker cards (Baker ch 5).

Each detector images a 20 x 40 mm patch of the marker plane at 300 mm (magnification 1/3, f = 75
mm; 5.1): card reflectance over its aperture (the element box-car convolved with the aperture of
fig 5.5), blurred by defocus off 300 mm, times an illumination fall-off with range and incidence
and a per-detector gain, plus an offset. Ambient light adds to lit and dark conversion alike (the
difference removes it) and can saturate the 8-bit ADC0809; both carry noise. Gains and black levels
default to values derived from Table 7.1 (`calibrate`). The lens sits `sensor_lateral` right of the
guide-wire sensor point, its axis horizontal, square to the truck, pointing right; column C1 looks
furthest forward, so a card passing in forward travel crosses the image from C1 to C4.
"""

import functools
import math
import random
from types import ModuleType

import numpy as np

from agv_nodes.markers import ELEMENT_HEIGHT, LOCATION_PATTERNS, trough_and_peak
from agv_nodes.result_cache import cached
from agv_nodes.world import kernels
from agv_nodes.world.marker_optics import (
    EDGE_ON,
    box_blur_cover,
    card_runs,
    cdf,
    detector_offsets,
    pack_cards,
    psi,
    ray,
)
from agv_nodes.world.settings import SensorParams

NOISE_PER_SNAPSHOT = 17  # standard normals a snapshot uses: 8 lit, 8 dark, 1 ambient
NOISE_BLOCK = 256  # snapshots whose noise is drawn (and converted) at once
# Lens-to-card ranges of the threshold experiment (Baker 1983, 7.1.2-7.1.3), which `calibrate`
# repeats: Table 7.1's thresholds are set for the worst of them.
CALIBRATION_RANGES = tuple(0.280 + 0.005 * k for k in range(9))
# The working range a layout is held to (agv_nodes/world/layout_check.py): the standoff band the
# thresholds hold over, and how far the card may be turned about the vertical from square to the
# optical axis (Baker 1983, 7.1.4, fig 7.13: recognition against angle, about +-10 degrees).
READ_STANDOFF = (CALIBRATION_RANGES[0], CALIBRATION_RANGES[-1])  # m along the optical axis
READ_ANGLE = 10.0  # degrees either way
def lens_position(sensor_point: tuple[float, float], heading: float,
                  lateral: float) -> tuple[float, float]:
    """Return the lens position: `lateral` m right of the sensor point, square to the truck."""
    return (sensor_point[0] + math.sin(heading) * lateral,
            sensor_point[1] - math.cos(heading) * lateral)


def axis_on_card(lens: tuple[float, float], heading: float,
                 card) -> tuple[float, float, float] | None:
    """(t range, u along the card, + downstream, cos incidence) of the axis; None if edge-on."""
    ax, ay = math.sin(heading), -math.cos(heading)
    nx, ny = card.normal
    denom = ax * nx + ay * ny
    if denom > EDGE_ON:
        return None
    dx, dy = lens[0] - card.centre[0], lens[1] - card.centre[1]
    t = -(dx * nx + dy * ny) / denom
    u = (dx + t * ax) * card.along[0] + (dy + t * ay) * card.along[1]
    return t, u, -denom


class MarkerSensorModel:
    """Produces (lit, dark) ADC snapshots for a lens pose among marker cards."""

    def __init__(self, params: SensorParams, rng: random.Random,
                 compiled: ModuleType | None = kernels.compiled) -> None:
        """`compiled`: the C kernels that run the optics (agv_nodes.world.kernels), or None."""
        self.p = params
        self.rng = rng
        # the kernel itself, not its module: a world is deep-copied (forked test states)
        self._look_kernel = compiled.marker_look if compiled is not None else None
        self._packed: tuple[tuple, np.ndarray] | None = None  # cards in view, as the C reads them
        self._optics: tuple[tuple, np.ndarray] | None = None  # the optics' figures, likewise
        # The conversions' noise comes in blocks of standard normals from a numpy generator
        # seeded from `rng` (17 random.gauss calls a snapshot were a tenth of the lock-step
        # harness's time), a row of 17 a snapshot, read in order. What of a conversion does not
        # depend on the signals (the base level, the dark conversions, the lit ones with no card
        # in view) is worked out for the whole block with numpy, in the same arithmetic.
        self._normals = np.random.default_rng(rng.getrandbits(64))
        self._z = np.zeros((0, NOISE_PER_SNAPSHOT))
        self._row = NOISE_BLOCK  # the next snapshot's row of the block (spent: draw anew)
        self._block_key: tuple | None = None  # the settings the block's conversions hold for
        self._base: list[float] = []  # per row: dark level + ambient + its noise
        self._base_block = np.zeros(0)  # the same, as numpy
        self._lit_noise = np.zeros((0, 8))  # per row: the lit conversions' noise, counts
        self._dark: list[list[int]] = []  # per row: the dark conversions
        self._quiet: tuple | None = None  # (gains, blacks, signals, lit) with no card in view
        self._seen_key: tuple | None = None  # what _seen_last was looked at from
        self._seen_last: list[tuple[int, tuple[float, float]]] = []
        gains, blacks = calibrate(params) if not params.gains or not params.blacks else ((), ())
        self.gains, self.blacks = params.gains or gains, params.blacks or blacks
        if len(self.gains) != 8 or len(self.blacks) != 8 or len(params.skew) != 8:
            raise ValueError('marker sensor: gains, blacks and skew need 8 values each')

    # -- optics -------------------------------------------------------------------------
    def optics(self, lens: tuple[float, float], heading: float, cards: list,
               height: float = 0.0) -> list[tuple[float, float]]:
        """Per detector 1..8: (illumination factor, fraction of the patch that is white)."""
        out = [(1.0, 0.0)] * 8  # nothing in view: black background
        for d, value in self._seen(lens, heading, cards, height):
            out[d] = value
        return out

    def _seen(self, lens: tuple[float, float], heading: float, cards: list,
              height: float) -> list[tuple[int, tuple[float, float]]]:
        """_look(), kept while the lens, its height and the cards near it stay as they were.

        A truck standing at a stop marker sees the same card sample after sample (a fleet's
        parked trucks for minutes), and the optics depend on nothing else. The key holds the
        cards themselves: the same objects compare at once, equal ones look alike.
        """
        key = (lens, heading, height, tuple(cards))
        if key != self._seen_key:
            self._seen_key, self._seen_last = key, self._look(lens, heading, cards, height)
        return self._seen_last

    def _look(self, lens: tuple[float, float], heading: float, cards: list,
              height: float) -> list[tuple[int, tuple[float, float]]]:
        """(detector, (illumination, white fraction)) of each detector a card is seen by.

        In card order (a later card's view of a detector replaces an earlier one's). Most
        samples have no card within 0.6 m: they cost one distance test per card. A card nearer
        than that is passed over when the outermost rays both meet its line beyond reach on the
        same side: the rays between them meet it between those points, no wider a patch or
        farther. The detector model is inline, its per-card and per-pose constants worked out
        once.
        """
        p = self.p
        lx, ly = lens
        if self._look_kernel is not None:
            return self._look_compiled(lens, heading, cards, height)
        seen: list[tuple[int, tuple[float, float]]] = []
        outer = rays = None
        for card in cards:
            cx, cy = card.centre
            dx, dy = cx - lx, cy - ly
            if dx * dx + dy * dy > 0.36:  # only cards within 0.6 m can be in view
                continue
            if outer is None:
                focus, blur, defocus = p.focus, p.base_blur, p.defocus_blur
                width, aperture, flat = p.aperture_width, p.aperture_height, p.flat_height
                up = p.row_pitch / 2.0
                offsets, first, last = detector_offsets(p.column_pitch, tuple(p.skew))
                fx, fy = math.cos(heading), math.sin(heading)  # forward
                # optical axis (fy, -fx), right of the truck, times the focus
                axis = (fy * focus, -fx * focus)
                outer = ray(axis, fx, fy, offsets[first]), ray(axis, fx, fy, offsets[last])
            nx, ny = card.normal
            ex, ey = card.along
            half_card, runs = card_runs(card.rows)
            # the outermost rays: where they meet the card's line, and the widest patch
            (r1x, r1y), (r2x, r2y) = outer
            den1, den2 = r1x * nx + r1y * ny, r2x * nx + r2y * ny
            if den1 <= EDGE_ON and den2 <= EDGE_ON:
                dn = dx * nx + dy * ny
                t1, t2 = dn / den1, dn / den2
                u1 = (lx + t1 * r1x - cx) * ex + (ly + t1 * r1y - cy) * ey
                u2 = (lx + t2 * r2x - cx) * ex + (ly + t2 * r2y - cy) * ey
                widest = width * (t1 if t1 > t2 else t2) / focus \
                    / max(-den1 if den1 > den2 else -den2, 0.3)
                reach = half_card + 0.02 + widest * (1.0 + 1e-9) + 1e-9  # margin: rounding
                if u1 > reach and u2 > reach or u1 < -reach and u2 < -reach:
                    continue
            lift = card.height + height
            if rays is None:
                rays = [ray(axis, fx, fy, x_off) for x_off in offsets]
            for d in range(8):
                rx, ry = rays[d]
                denom = rx * nx + ry * ny
                if denom > EDGE_ON:  # card seen edge-on or from behind
                    continue
                t = (dx * nx + dy * ny) / denom
                if not 0.05 < t < 0.8:
                    continue
                u = (lx + t * rx - cx) * ex + (ly + t * ry - cy) * ey
                cos_inc = -denom
                scale = t / focus
                w = width * scale / (0.3 if 0.3 > cos_inc else cos_inc)
                if abs(u) > half_card + w + 0.02:
                    continue
                sigma = math.hypot(blur, defocus * (t - focus))
                lo, hi = u - w / 2.0, u + w / 2.0
                # Vertical: patch centre in card coordinates (card centre = 0, up +).
                v = (up if d < 4 else -up) * scale - lift
                b = aperture * scale / 2.0
                a = flat * b
                middle = cdf(0.0 - v, a, b)
                white_cover = 0.0
                for row_runs, weight in zip(runs, (
                        (cdf(ELEMENT_HEIGHT - v, a, b) - middle) / (a + b),
                        (middle - cdf(-ELEMENT_HEIGHT - v, a, b)) / (a + b)), strict=True):
                    if weight <= 1e-6:
                        continue
                    cover = 0.0
                    for ra, rb in row_runs:
                        if sigma <= 0.0:
                            cover += box_blur_cover(ra, rb, lo, hi, sigma)
                            continue
                        # box_blur_cover inline; psi is 0 at and below -8.5, z at and above
                        # 8.5: a run 8.5 sigma short of the patch adds nothing
                        z1 = (rb - lo) / sigma
                        if z1 <= -8.5:
                            continue
                        z2, z3, z4 = (rb - hi) / sigma, (ra - lo) / sigma, (ra - hi) / sigma
                        if z4 >= 8.5:  # the smallest
                            cover += sigma * (z1 - z2 - z3 + z4)
                        else:
                            cover += sigma * (psi(z1) - psi(z2) - psi(z3) + psi(z4))
                    white_cover += weight * cover / w
                seen.append((d, ((focus / t) ** 2 * cos_inc, white_cover)))
        return seen

    def _look_compiled(self, lens: tuple[float, float], heading: float, cards: list,
                       height: float) -> list[tuple[int, tuple[float, float]]]:
        """_look() in C (agv_nodes.world.kernels): the cards within 0.6 m, packed once."""
        lx, ly = lens
        nearby = []
        for card in cards:  # the test _look makes first, as it makes it
            dx, dy = card.centre[0] - lx, card.centre[1] - ly
            if dx * dx + dy * dy <= 0.36:
                nearby.append(card)
        near = tuple(nearby)
        if not near:
            return []
        packed = self._packed
        if packed is None or packed[0] != near:
            packed = self._packed = (near, pack_cards(near))
        p = self.p
        key = (p.focus, p.base_blur, p.defocus_blur, p.aperture_width, p.aperture_height,
               p.flat_height, p.row_pitch, p.column_pitch, tuple(p.skew))
        optics = self._optics
        if optics is None or optics[0] != key:
            offsets, first, last = detector_offsets(p.column_pitch, tuple(p.skew))
            optics = self._optics = (key, np.array(
                [*key[:6], p.row_pitch / 2.0, ELEMENT_HEIGHT, *offsets, first, last],
                dtype=float))
        kernel = self._look_kernel
        if kernel is None:  # _look asks only where the kernels were built
            raise RuntimeError('marker sensor: no compiled kernel to look with')
        return kernel(packed[1], optics[1], lx, ly, heading, height)

    # -- electronics ----------------------------------------------------------------------
    def signals(self, optics: list[tuple[float, float]]) -> list[float]:
        """Noise-free on-minus-off signal of each detector, ADC counts."""
        return [g * illum * (b + (1.0 - b) * cover)
                for g, b, (illum, cover) in zip(self.gains, self.blacks, optics, strict=True)]

    def adc(self, signals: list[float]) -> tuple[list[int], list[int]]:
        """Lit and dark 8-bit conversions: ambient and noise on both, the IRED signal on lit."""
        row = self._next_row()
        return self._lit(row, signals), self._dark[row]

    def snapshot(self, lens: tuple[float, float], heading: float, cards: list,
                 height: float = 0.0) -> tuple[list[int], list[int]]:
        """One on/off snapshot: (lit[8], dark[8]) ADC counts.

        adc(signals(optics(...))), with what no card is seen by worked out once: the signals of
        such detectors, and with no card in view at all the whole snapshot (a block's worth at
        a time); test_world_speed_paths holds the two to the same counts.
        """
        seen = self._seen(lens, heading, cards, height) if cards else ()
        row = self._next_row()
        gains, blacks = self.gains, self.blacks
        quiet = self._quiet
        if quiet is None or quiet[0] is not gains or quiet[1] is not blacks:
            signals = self.signals([(1.0, 0.0)] * 8)
            quiet = self._quiet = (gains, blacks, signals, self._quiet_lit(signals))
        elif quiet[3] is None:
            quiet = self._quiet = quiet[:3] + (self._quiet_lit(quiet[2]),)
        if not seen:
            return quiet[3][row], self._dark[row]
        signals = list(quiet[2])
        for d, (illum, cover) in seen:
            b = blacks[d]
            signals[d] = gains[d] * illum * (b + (1.0 - b) * cover)
        return self._lit(row, signals), self._dark[row]

    def _next_row(self) -> int:
        """Return this snapshot's row of the noise block (drawn, converted when spent, stale)."""
        p = self.p
        key = (p.dark_level, p.ambient, p.ambient_noise, p.noise)
        row = self._row
        if row >= NOISE_BLOCK:
            self._z = self._normals.standard_normal(
                NOISE_PER_SNAPSHOT * NOISE_BLOCK).reshape(NOISE_BLOCK, NOISE_PER_SNAPSHOT)
            row, self._block_key = 0, None
        if key != self._block_key:  # a new block, or the settings changed (the ambient light)
            self._block_key = key
            z = self._z
            base = (p.dark_level + p.ambient) + z[:, 16] * p.ambient_noise
            self._base_block, self._base = base, base.tolist()
            # kept as numpy: a lit row is turned into floats only where a card is seen
            self._lit_noise = z[:, :8] * p.noise
            self._dark = _adc8(base[:, None] + z[:, 8:16] * p.noise).tolist()
            if self._quiet is not None:
                self._quiet = self._quiet[:3] + (None,)
        self._row = row + 1
        return row

    def _quiet_lit(self, signals: list[float]) -> list[list[int]]:
        """Return the lit conversions of each row of the block with these signals."""
        return _adc8((self._base_block[:, None] + np.array(signals))
                     + self._lit_noise).tolist()

    def _lit(self, row: int, signals: list[float]) -> list[int]:
        base = self._base[row]
        return [0 if (x := base + s + n) <= 0 else 255 if x >= 255 else int(x + 0.5)
                for s, n in zip(signals, self._lit_noise[row].tolist(), strict=True)]


def _adc8(value: np.ndarray) -> np.ndarray:
    """8-bit conversion of each value, as int(v + 0.5) within 0..255."""
    return np.where(value <= 0, 0, np.where(value >= 255, 255, np.floor(value + 0.5))) \
        .astype(np.int64)


# -- calibration from Table 7.1 ---------------------------------------------------------------
class _Belt:
    """A long strip of the location-2 pattern: the continuous belt of thesis 7.1.2."""

    def __init__(self, standoff: float, elements: int = 60) -> None:
        r1, r2 = LOCATION_PATTERNS[2]
        self.rows = (r1 * (elements // 4), r2 * (elements // 4))
        self.columns = len(self.rows[0])
        self.height = 0.0
        self.centre = (0.0, -standoff)  # on the right of a lens at the origin heading +x
        self.normal = (0.0, 1.0)  # facing the lens
        self.along = (1.0, 0.0)  # downstream = the direction of travel


@functools.cache
def _belt_runs(params_key: tuple) -> tuple:
    """Run the threshold experiment of Baker 1983, 7.1.2-7.1.3 for a unit detector.

    Location-2's alternating pattern at 1 m/s, 256 samples at 340 Hz a run, 280-320 mm in 5 mm
    steps: per range and detector the mean over peaks and troughs of the x4 running sum of the
    black part X = illum (1 - cover) and the white part Y = illum cover (a detector: A X + B Y).
    A third of a second of Python optics, so kept on disk by its inputs (result_cache) like the
    layout check: every world process and lock-step truck calibrates at start-up.
    """
    runs = cached('belt_runs', repr(params_key), lambda: _run_belt(params_key))
    # JSON keeps every float exactly (shortest repr); the tuples come back as lists
    return tuple(tuple(tuple(tuple(level) for level in detector) for detector in run)
                 for run in runs)


def _run_belt(params_key: tuple) -> tuple:
    model = MarkerSensorModel.__new__(MarkerSensorModel)  # the optics alone: no calibration
    model.p = SensorParams(**dict(params_key))
    model._seen_key, model._seen_last = None, []
    model._look_kernel = None  # the Python optics (the C gives the same bits)
    runs = []
    for standoff in CALIBRATION_RANGES:
        belt = _Belt(standoff)
        series = [model.optics((-0.35 + k / 340.0, 0.0), 0.0, [belt]) for k in range(256 + 3)]
        per_detector = []
        for d in range(8):
            x = [series[i][d][0] * (1 - series[i][d][1]) for i in range(len(series))]
            y = [series[i][d][0] * series[i][d][1] for i in range(len(series))]
            sx = [x[i] + x[i - 1] + x[i - 2] + x[i - 3] for i in range(3, len(x))]
            sy = [y[i] + y[i - 1] + y[i - 2] + y[i - 3] for i in range(3, len(y))]
            inner = range(1, len(sy) - 1)
            peaks = [i for i in inner if sy[i] >= sy[i - 1] and sy[i] > sy[i + 1]]
            troughs = [i for i in inner if sy[i] <= sy[i - 1] and sy[i] < sy[i + 1]]
            per_detector.append((
                (sum(sx[i] for i in peaks) / len(peaks), sum(sy[i] for i in peaks) / len(peaks)),
                (sum(sx[i] for i in troughs) / len(troughs),
                 sum(sy[i] for i in troughs) / len(troughs))))
        runs.append(per_detector)
    return tuple(runs)


def belt_key(params: SensorParams) -> tuple:
    """Return the settings the threshold experiment depends on (not the calibration's own)."""
    return tuple(sorted((k, v) for k, v in vars(params).items()
                        if k not in ('gains', 'blacks', 'unit', 'noise', 'ambient',
                                     'ambient_noise', 'dark_level')))


def calibrate(params: SensorParams) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Per-detector gains and black levels that reproduce Table 7.1.

    With threshold = trough + {0.2, 0.8} x amplitude (Baker 1983, 7.1.3), Table 7.1 gives each
    detector's worst-case mean trough and peak of the x4 running sum over 28 +- 2 cm. The model is
    linear in A = gain x black and B = gain, so the simulated threshold experiment fixes both. A is
    kept >= 0 (no detector sees less than no light): where the optics cannot reach the table's
    contrast, the black level is 0 and the worst trough lies above the table's (below the black
    threshold).
    """
    runs = _belt_runs(belt_key(params))
    gains, blacks = [], []
    for d, (trough, peak) in enumerate(trough_and_peak(params.unit)):
        a, b = 0.0, 1.0
        for _ in range(5):  # the worst range depends weakly on A/B: iterate to a fixed point
            pk = min((r[d][0] for r in runs), key=lambda v: a * v[0] + b * v[1])
            tr = max((r[d][1] for r in runs), key=lambda v: a * v[0] + b * v[1])
            det = pk[0] * tr[1] - pk[1] * tr[0]
            a = (peak * tr[1] - trough * pk[1]) / det
            b = (pk[0] * trough - tr[0] * peak) / det
            if a < 0.0:
                a, b = 0.0, peak / pk[1]
        gains.append(b)
        blacks.append(a / b)
    return tuple(gains), tuple(blacks)
