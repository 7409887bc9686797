"""The marker sensor's optics, the arithmetic of one detector's view of a card (ROS-free).

What MarkerSensorModel (agv_nodes/world/marker_sensor.py) composes into a snapshot: each card
row's white runs, the patch blurred by defocus (a Gaussian) over the element box-car, the
aperture's trapezoid in height, the detectors' rays, and the cards packed for the C optics
(agv_nodes/world/_kernels.c, marker_look). Baker 1983, 5.1, fig 5.5.
"""

import functools
import math

import numpy as np

from agv_nodes.markers import ELEMENT_WIDTH

EDGE_ON = -0.2  # cosine of incidence (negated) beyond which a card is seen edge-on or from behind
SQRT2 = math.sqrt(2.0)
INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)


def psi(z: float) -> float:
    """Antiderivative of the standard normal CDF: z Phi(z) + phi(z)."""
    # Beyond 8.5 sigma the tails are below a double's resolution of the result (Phi = 1 or 0
    # exactly, phi < 1e-16): most runs of a card lie that far from a detector's patch, and
    # the erf and exp are most of the optics' cost.
    if z >= 8.5:
        return z
    if z <= -8.5:
        return 0.0
    return z * 0.5 * (1.0 + math.erf(z / SQRT2)) + INV_SQRT_2PI * math.exp(-0.5 * z * z)


@functools.cache
def detector_offsets(pitch: float, skew: tuple[float, ...]) -> tuple[tuple[float, ...], int, int]:
    """Each detector's patch offset forward (m at the focus); the outermost two's detectors."""
    offsets = tuple((1.5 - d % 4) * pitch + skew[d] for d in range(8))
    return offsets, offsets.index(min(offsets)), offsets.index(max(offsets))


def ray(axis: tuple[float, float], fx: float, fy: float, x_off: float) -> tuple[float, float]:
    """Return the unit ray through a detector's patch: axis*focus + forward*x_off."""
    rx, ry = axis[0] + fx * x_off, axis[1] + fy * x_off
    norm = math.hypot(rx, ry)
    return rx / norm, ry / norm


def pack_cards(cards: tuple) -> np.ndarray:
    """Return the cards as the C optics reads them (agv_nodes/world/_kernels.c, marker_look)."""
    out: list[float] = []
    for card in cards:
        half_card, runs = card_runs(card.rows)
        if len(runs) != 2:
            raise ValueError(f'marker card with {len(runs)} rows: the sensor reads two')
        out += [*card.centre, *card.normal, *card.along, card.height, half_card,
                len(runs[0]), len(runs[1])]
        for row in runs:
            for a, b in row:
                out += [a, b]
    return np.array(out, dtype=float)


@functools.cache
def card_runs(rows: tuple[str, ...]) -> tuple[float, tuple[tuple[tuple[float, float], ...], ...]]:
    """Half the card's length and each row's white runs, m from the card centre (downstream +)."""
    half_card = len(rows[0]) * ELEMENT_WIDTH / 2.0
    return half_card, tuple(tuple((a - half_card, b - half_card) for a, b in white_runs(row))
                            for row in rows)


@functools.cache
def white_runs(row: str) -> tuple[tuple[float, float], ...]:
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


def box_blur_cover(a: float, b: float, lo: float, hi: float, sigma: float) -> float:
    """Integral over [lo, hi] of the Gaussian-blurred indicator of [a, b] (m)."""
    if sigma <= 0.0:
        return max(0.0, min(b, hi) - max(a, lo))
    s = sigma
    return s * (psi((b - lo) / s) - psi((b - hi) / s) - psi((a - lo) / s) + psi((a - hi) / s))


def cdf(z: float, a: float, b: float) -> float:
    """Mass of the trapezoid (flat top -a..a, feet -b..b; a + b in all) below z."""
    if z <= -b:
        return 0.0
    if z < -a:
        return (z + b) ** 2 / (2.0 * (b - a))
    if z <= a:
        return (b - a) / 2.0 + (z + a)
    if z < b:
        return (a + b) - (b - z) ** 2 / (2.0 * (b - a))
    return a + b
