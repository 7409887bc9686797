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

import numpy as np

from agv_nodes.markers import ELEMENT_HEIGHT, ELEMENT_WIDTH, LOCATION_PATTERNS, trough_and_peak
from agv_nodes.world.settings import SensorParams

NOISE_PER_SNAPSHOT = 17  # standard normals a snapshot uses: 8 lit, 8 dark, 1 ambient
# Lens-to-card ranges of the threshold experiment (Baker 1983, 7.1.2-7.1.3), which `calibrate`
# repeats: Table 7.1's thresholds are set for the worst of them.
CALIBRATION_RANGES = tuple(0.280 + 0.005 * k for k in range(9))
# The working range a layout is held to (agv_nodes/world/layout_check.py): the standoff band the
# thresholds hold over, and how far the card may be turned about the vertical from square to the
# optical axis (Baker 1983, 7.1.4, fig 7.13: recognition against angle, about +-10 degrees).
READ_STANDOFF = (CALIBRATION_RANGES[0], CALIBRATION_RANGES[-1])  # m along the optical axis
READ_ANGLE = 10.0  # degrees either way
EDGE_ON = -0.2  # cosine of incidence (negated) beyond which a card is seen edge-on or from behind
SQRT2 = math.sqrt(2.0)
INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


def _psi(z: float) -> float:
    """Antiderivative of the standard normal CDF: z Phi(z) + phi(z)."""
    # Beyond 8.5 sigma the tails are below a double's resolution of the result (Phi = 1 or 0
    # exactly, phi < 1e-16): most runs of a card lie that far from a detector's patch, and
    # the erf and exp are most of the optics' cost.
    if z >= 8.5:
        return z
    if z <= -8.5:
        return 0.0
    return z * 0.5 * (1.0 + math.erf(z / SQRT2)) + INV_SQRT_2PI * math.exp(-0.5 * z * z)


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

    def __init__(self, params: SensorParams, rng: random.Random) -> None:
        self.p = params
        self.rng = rng
        # The conversions' noise comes in blocks of standard normals from a numpy generator
        # seeded from `rng` (17 random.gauss calls a snapshot were a tenth of the lock-step
        # harness's time); the block is a list of floats, read in order.
        self._normals = np.random.default_rng(rng.getrandbits(64))
        self._noise: list[float] = []
        self._noise_at = 0
        gains, blacks = calibrate(params) if not params.gains or not params.blacks else ((), ())
        self.gains, self.blacks = params.gains or gains, params.blacks or blacks
        if len(self.gains) != 8 or len(self.blacks) != 8 or len(params.skew) != 8:
            raise ValueError('marker sensor: gains, blacks and skew need 8 values each')

    # -- optics -------------------------------------------------------------------------
    def optics(self, lens: tuple[float, float], heading: float, cards: list,
               height: float = 0.0) -> list[tuple[float, float]]:
        """Per detector 1..8: (illumination factor, fraction of the patch that is white)."""
        p = self.p
        fx, fy = math.cos(heading), math.sin(heading)  # forward
        ax, ay = fy, -fx  # optical axis: right of the truck
        out = [(1.0, 0.0)] * 8  # nothing in view: black background
        for card in cards:
            cx, cy = card.centre
            nx, ny = card.normal
            ex, ey = card.along
            dx, dy = cx - lens[0], cy - lens[1]
            if dx * dx + dy * dy > 0.36:  # only cards within 0.6 m can be in view
                continue
            for d in range(8):
                column = d % 4
                x_off = (1.5 - column) * p.column_pitch + p.skew[d]
                # Ray through this detector's patch: axis*focus + forward*x_off.
                rx, ry = ax * p.focus + fx * x_off, ay * p.focus + fy * x_off
                norm = math.hypot(rx, ry)
                rx, ry = rx / norm, ry / norm
                denom = rx * nx + ry * ny
                if denom > EDGE_ON:  # card seen edge-on or from behind
                    continue
                t = (dx * nx + dy * ny) / denom
                if not 0.05 < t < 0.8:
                    continue
                hx, hy = lens[0] + t * rx - cx, lens[1] + t * ry - cy
                u = hx * ex + hy * ey
                value = self._detector(card, d, u, t, -denom, height)
                if value is not None:
                    out[d] = value
        return out

    def _detector(self, card, d: int, u: float, rng_: float, cos_inc: float,
                  height: float) -> tuple[float, float] | None:
        p = self.p
        n = card.columns
        half_card = n * ELEMENT_WIDTH / 2.0
        scale = rng_ / p.focus
        w = p.aperture_width * scale / max(cos_inc, 0.3)
        if abs(u) > half_card + w + 0.02:
            return None
        sigma = math.hypot(p.base_blur, p.defocus_blur * (rng_ - p.focus))
        lo, hi = u - w / 2.0, u + w / 2.0
        # Vertical: patch centre in card coordinates (card centre = 0, up +).
        v = (p.row_pitch / 2.0 if d < 4 else -p.row_pitch / 2.0) * scale - (card.height + height)
        big = p.aperture_height * scale
        weights = (_trapezoid_mass(0.0 - v, ELEMENT_HEIGHT - v, big, p.flat_height),
                   _trapezoid_mass(-ELEMENT_HEIGHT - v, 0.0 - v, big, p.flat_height))
        white_cover = 0.0
        for row, weight in zip(card.rows, weights, strict=True):
            if weight <= 1e-6:
                continue
            cover = 0.0
            for a, b in _white_runs(row):
                cover += _box_blur_cover(a - half_card, b - half_card, lo, hi, sigma)
            white_cover += weight * cover / w
        return (p.focus / rng_) ** 2 * cos_inc, white_cover

    # -- electronics ----------------------------------------------------------------------
    def signals(self, optics: list[tuple[float, float]]) -> list[float]:
        """Noise-free on-minus-off signal of each detector, ADC counts."""
        return [g * illum * (b + (1.0 - b) * cover)
                for g, b, (illum, cover) in zip(self.gains, self.blacks, optics, strict=True)]

    def adc(self, signals: list[float]) -> tuple[list[int], list[int]]:
        """Lit and dark 8-bit conversions: ambient and noise on both, the IRED signal on lit."""
        p = self.p
        at = self._noise_at
        if at + NOISE_PER_SNAPSHOT > len(self._noise):
            self._noise = self._normals.standard_normal(NOISE_PER_SNAPSHOT * 256).tolist()
            at = 0
        self._noise_at = at + NOISE_PER_SNAPSHOT
        z = self._noise[at:at + NOISE_PER_SNAPSHOT]
        sigma = p.noise
        base = p.dark_level + p.ambient + z[16] * p.ambient_noise
        lit = [_adc8(base + signals[d] + z[d] * sigma) for d in range(8)]
        dark = [_adc8(base + z[8 + d] * sigma) for d in range(8)]
        return lit, dark

    def snapshot(self, lens: tuple[float, float], heading: float, cards: list,
                 height: float = 0.0) -> tuple[list[int], list[int]]:
        """One on/off snapshot: (lit[8], dark[8]) ADC counts."""
        return self.adc(self.signals(self.optics(lens, heading, cards, height)))


def _adc8(value: float) -> int:
    return 0 if value <= 0 else 255 if value >= 255 else int(value + 0.5)


@functools.cache
def _white_runs(row: str) -> tuple[tuple[float, float], ...]:
    """White runs (start, end) of a card row, m from its upstream end (C1, j = 0, downstream)."""
    n = len(row)
    runs: list[tuple[float, float]] = []
    for j, ch in enumerate(row):
        if ch != 'W':
            continue
        a, b = (n - 1 - j) * ELEMENT_WIDTH, (n - j) * ELEMENT_WIDTH
        if runs and abs(runs[-1][0] - b) < 1e-12:
            runs[-1] = (a, runs[-1][1])
        else:
            runs.append((a, b))
    return tuple(runs)


def _box_blur_cover(a: float, b: float, lo: float, hi: float, sigma: float) -> float:
    """Integral over [lo, hi] of the Gaussian-blurred indicator of [a, b] (m)."""
    if sigma <= 0.0:
        return max(0.0, min(b, hi) - max(a, lo))
    s = sigma
    return s * (_psi((b - lo) / s) - _psi((b - hi) / s) - _psi((a - lo) / s) + _psi((a - hi) / s))


def _trapezoid_mass(z0: float, z1: float, height: float, flat: float) -> float:
    """Fraction of a trapezoidal vertical aperture (centred on 0) lying in [z0, z1]."""
    b = height / 2.0
    a = flat * b

    def cdf(z: float) -> float:
        if z <= -b:
            return 0.0
        if z < -a:
            return (z + b) ** 2 / (2.0 * (b - a))
        if z <= a:
            return (b - a) / 2.0 + (z + a)
        if z < b:
            return (a + b) - (b - z) ** 2 / (2.0 * (b - a))
        return a + b

    return (cdf(z1) - cdf(z0)) / (a + b)


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
    """
    model = MarkerSensorModel.__new__(MarkerSensorModel)
    model.p = SensorParams(**dict(params_key))
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


def calibrate(params: SensorParams) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Per-detector gains and black levels that reproduce Table 7.1.

    With threshold = trough + {0.2, 0.8} x amplitude (Baker 1983, 7.1.3), Table 7.1 gives each
    detector's worst-case mean trough and peak of the x4 running sum over 28 +- 2 cm. The model is
    linear in A = gain x black and B = gain, so the simulated threshold experiment fixes both. A is
    kept >= 0 (no detector sees less than no light): where the optics cannot reach the table's
    contrast, the black level is 0 and the worst trough lies above the table's (below the black
    threshold).
    """
    key = tuple(sorted((k, v) for k, v in vars(params).items()
                       if k not in ('gains', 'blacks', 'unit', 'noise', 'ambient',
                                    'ambient_noise', 'dark_level')))
    runs = _belt_runs(key)
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
