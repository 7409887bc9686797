"""Guide-wire pickup: two coils either side of the sensor point, in the field of line currents.

Each wire section is a polyline carrying an a.c. line current. Biot-Savart for a finite straight
segment gives the field at a coil; each coil's axis is horizontal and square to the truck (the
lateral axis), so it reads the lateral field component, rectified. Over a straight wire a coil
at height h and lateral distance y reads ~ h / (h^2 + y^2): equal in both coils when the sensor
point is over the wire, unequal to one side, and falling off to nothing far from every wire.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from agv_nodes.world.layout import Path2D


@dataclass
class PickupParams:
    """Coil geometry and scaling ([A])."""

    coil_spacing: float = 0.20  # m between the two coils (each 0.10 m off centre)
    coil_height: float = 0.08  # m above the wire
    gain: float = 75.0  # ADC counts per unit of 2h/(h^2 + y^2) (1/m); 12-bit full scale 4095
    noise: float = 2.0  # counts rms
    reach: float = 1.5  # m: wire segments farther than this are ignored

    @property
    def nominal(self) -> float:
        """Counts of each coil with the sensor point right over a long straight wire."""
        h, y = self.coil_height, self.coil_spacing / 2.0
        return self.gain * 2.0 * h / (h * h + y * y)


class GuideWirePickup:
    """Computes the two coil amplitudes for a sensor pose."""

    def __init__(self, params: PickupParams, wires: list[Path2D], rng) -> None:
        self.p = params
        self.rng = rng
        starts, ends, currents = [], [], []
        for w in wires:
            for a, b in _merge_collinear(w.points):
                starts.append(a)
                ends.append(b)
                currents.append(w.current)
        a = np.array(starts, dtype=float).reshape(-1, 2)
        b = np.array(ends, dtype=float).reshape(-1, 2)
        seg = b - a
        self._length = np.linalg.norm(seg, axis=1)
        keep = self._length > 0
        self._a = a[keep]
        self._u = seg[keep] / self._length[keep, None]
        self._length = self._length[keep]
        self._current = np.array(currents)[keep]
        self._mid = 0.5 * (a[keep] + b[keep])

    def field(self, xy: np.ndarray) -> np.ndarray:
        """Field vectors (arbitrary units, z up) at floor points `xy` (k, 2), coil height up."""
        h = self.p.coil_height
        centre = xy.mean(axis=0)
        near = (np.linalg.norm(self._mid - centre, axis=1) - 0.5 * self._length) < self.p.reach
        out = np.zeros((len(xy), 3))
        if not near.any():
            return out
        a, u, length, current = self._a[near], self._u[near], self._length[near], \
            self._current[near]
        ux, uy = u[:, 0], u[:, 1]
        # every point against every near segment at once: (k points, n segments)
        rx = xy[:, 0:1] - a[:, 0]  # the segment in the floor plane z = 0
        ry = xy[:, 1:2] - a[:, 1]
        along = rx * ux + ry * uy
        px, py = rx - along * ux, ry - along * uy
        rho2 = px * px + py * py + h * h
        beyond = along - length
        # |B| = I/(4 pi rho) (cos a1 - cos a2), direction u x rho_hat (rho_hat has z = h/rho);
        # u = (ux, uy, 0), rho_vec = (px, py, h): u x rho = (uy h, -ux h, ux py - uy px)
        mag = current * (along / np.sqrt(along * along + rho2)
                         - beyond / np.sqrt(beyond * beyond + rho2)) / (4 * math.pi * rho2)
        out[:, 0] = (mag * uy).sum(axis=1) * h
        out[:, 1] = -(mag * ux).sum(axis=1) * h
        out[:, 2] = (mag * (ux * py - uy * px)).sum(axis=1)
        return out

    def coils(self, x: float, y: float, heading: float) -> tuple[int, int]:
        """Rectified (left, right) coil amplitudes in 12-bit ADC counts."""
        half = self.p.coil_spacing / 2.0
        lx, ly = -math.sin(heading), math.cos(heading)  # left unit vector = coil axis
        points = np.array([[x + half * lx, y + half * ly], [x - half * lx, y - half * ly]])
        out = []
        for bx, by, _bz in self.field(points):
            amplitude = abs(bx * lx + by * ly) * 4 * math.pi  # lateral component, rectified
            value = self.p.gain * amplitude + self.rng.gauss(0.0, self.p.noise)
            out.append(int(min(max(round(value), 0), 4095)))
        return out[0], out[1]


def _merge_collinear(points: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Segments of a polyline with collinear runs merged (exact for Biot-Savart)."""
    segments: list[tuple[np.ndarray, np.ndarray]] = []
    start = points[0]
    for i in range(1, len(points) - 1):
        d0 = points[i] - start
        d1 = points[i + 1] - points[i]
        cross = d0[0] * d1[1] - d0[1] * d1[0]
        if abs(cross) > 1e-9 * (np.linalg.norm(d0) * np.linalg.norm(d1) + 1e-12):
            segments.append((start, points[i]))
            start = points[i]
    segments.append((start, points[-1]))
    return segments
