"""Guide-wire pickup: two coils either side of the sensor point, in the field of line currents.

Each wire section is a polyline carrying an a.c. current; Biot-Savart for a finite straight segment
gives the field at a coil, whose axis is horizontal and square to the truck, so it reads the
rectified lateral component: over a straight wire ~ h / (h^2 + y^2) at height h and lateral
distance y, equal in both coils over the wire, falling off to nothing far from every wire.
"""

import math
from types import ModuleType

import numpy as np

from agv_nodes.world import kernels
from agv_nodes.world.layout import Path2D
from agv_nodes.world.settings import PickupParams

NEAR_MOVE = 0.5  # m the sensor may move before `coils` refreshes its list of candidates
SCALAR_SEGMENTS = 12  # up to this many candidates `coils` sums in scalar arithmetic


class GuideWirePickup:
    """Computes the two coil amplitudes for a sensor pose."""

    def __init__(self, params: PickupParams, wires: list[Path2D], rng,
                 compiled: ModuleType | None = kernels.compiled) -> None:
        """`compiled`: the C kernels that sum the field (agv_nodes.world.kernels), or None."""
        self.p = params
        self.rng = rng
        # the kernel itself, not its module: a world is deep-copied (forked test states)
        self._lateral_kernel = compiled.wire_lateral if compiled is not None else None
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
        # The same segments as plain tuples for `coils`, which runs at 100 Hz on two points:
        # numpy's per-call overhead on a handful of segments cost more than the arithmetic.
        self._segments = [
            (float(ax), float(ay), float(ux), float(uy), float(length), float(current),
             float(mx), float(my))
            for (ax, ay), (ux, uy), length, current, (mx, my) in zip(
                self._a, self._u, self._length, self._current, self._mid, strict=True)]
        self._near: list[tuple[float, ...]] = []  # candidates within reach + NEAR_MOVE
        self._near_idx = np.zeros(0, dtype=int)  # their indices
        self._near_mid = np.zeros((0, 2))
        self._near_length = np.zeros(0)
        # their a, u, length and current as rows (ax, ay, ux, uy, length, current): one
        # selection a call, where `field` indexes four arrays
        self._near_rows = np.zeros((6, 0))
        self._near_mid_x = self._near_mid_y = self._near_half = np.zeros(0)
        self._near_table = np.zeros((8, 0))
        self._near_at = (math.inf, math.inf)

    def field(self, xy: np.ndarray, segments: np.ndarray | None = None) -> np.ndarray:
        """Field (z up) at floor points `xy` (k, 2), coil height up: `segments` or all in reach."""
        h = self.p.coil_height
        near = segments
        if near is None:
            centre = xy.mean(axis=0)
            near = np.flatnonzero(
                np.linalg.norm(self._mid - centre, axis=1) - 0.5 * self._length < self.p.reach)
        out = np.zeros((len(xy), 3))
        if not len(near):
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
        """Rectified (left, right) coil amplitudes in 12-bit ADC counts.

        The lateral component of `field` over the segments within `reach` of the coils, from a
        candidate list refreshed each NEAR_MOVE of travel: scalar arithmetic on a straight (a few
        segments, where numpy's per-call overhead costs more) and numpy on a curve (hundreds of
        short segments); test_world checks both against `field`.
        """
        half = self.p.coil_spacing / 2.0
        lx, ly = -math.sin(heading), math.cos(heading)  # left unit vector = coil axis
        if math.hypot(x - self._near_at[0], y - self._near_at[1]) > NEAR_MOVE:
            self._refresh_near(x, y)
        points = ((x + half * lx, y + half * ly), (x - half * lx, y - half * ly))
        if self._lateral_kernel is not None:  # the same arithmetic in C (world.kernels)
            (p0x, p0y), (p1x, p1y) = points
            lateral = self._lateral_kernel(
                self._near_table, x, y, lx, ly, p0x, p0y, p1x, p1y, self.p.coil_height,
                self.p.reach, len(self._near) <= SCALAR_SEGMENTS)
        elif len(self._near) > SCALAR_SEGMENTS:
            lateral = self._lateral_numpy(points, x, y, lx, ly)
        else:
            lateral = self._lateral_scalar(points, x, y, lx, ly)
        gain, noise, gauss = self.p.gain, self.p.noise, self.rng.gauss
        left = round(gain * abs(lateral[0]) * 4 * math.pi + gauss(0.0, noise))
        right = round(gain * abs(lateral[1]) * 4 * math.pi + gauss(0.0, noise))
        return (0 if left < 0 else 4095 if left > 4095 else int(left),
                0 if right < 0 else 4095 if right > 4095 else int(right))

    def _refresh_near(self, x: float, y: float) -> None:
        reach = self.p.reach + NEAR_MOVE
        self._near_idx = np.flatnonzero(
            np.hypot(self._mid[:, 0] - x, self._mid[:, 1] - y) - 0.5 * self._length < reach)
        self._near = [self._segments[i] for i in self._near_idx]
        self._near_mid = self._mid[self._near_idx]
        self._near_length = self._length[self._near_idx]
        i = self._near_idx
        self._near_rows = np.array([self._a[i, 0], self._a[i, 1], self._u[i, 0], self._u[i, 1],
                                    self._length[i], self._current[i]])
        self._near_mid_x = self._near_mid[:, 0].copy()
        self._near_mid_y = self._near_mid[:, 1].copy()
        self._near_half = 0.5 * self._near_length
        # the C kernel's rows: a, u, length, current and the middles, one contiguous table
        self._near_table = np.ascontiguousarray(np.vstack(
            (self._near_rows, self._near_mid_x, self._near_mid_y)))
        self._near_at = (x, y)

    def _lateral_numpy(self, points, x: float, y: float, lx: float, ly: float) -> list[float]:
        """`field`'s arithmetic on the candidates in reach, x and y components only."""
        keep = np.hypot(self._near_mid_x - x, self._near_mid_y - y) - self._near_half \
            < self.p.reach
        ax, ay, ux, uy, length, current = self._near_rows[:, keep]
        if not len(ax):
            return [0.0 * lx + 0.0 * ly] * 2
        h = self.p.coil_height
        (p0x, p0y), (p1x, p1y) = points
        rx = np.array([[p0x], [p1x]]) - ax
        ry = np.array([[p0y], [p1y]]) - ay
        along = rx * ux + ry * uy
        px, py = rx - along * ux, ry - along * uy
        rho2 = px * px + py * py + h * h
        beyond = along - length
        mag = current * (along / np.sqrt(along * along + rho2)
                         - beyond / np.sqrt(beyond * beyond + rho2)) / (4 * math.pi * rho2)
        bx = ((mag * uy).sum(axis=1) * h).tolist()
        by = (-(mag * ux).sum(axis=1) * h).tolist()
        return [bx[0] * lx + by[0] * ly, bx[1] * lx + by[1] * ly]

    def _lateral_scalar(self, points, x: float, y: float, lx: float, ly: float) -> list[float]:
        near = [s for s in self._near
                if math.hypot(s[6] - x, s[7] - y) - 0.5 * s[4] < self.p.reach]
        h = self.p.coil_height
        h2 = h * h
        sqrt = math.sqrt
        lateral = []
        for px_, py_ in points:
            bx = by = 0.0
            for ax, ay, ux, uy, length, current, _mx, _my in near:
                rx, ry = px_ - ax, py_ - ay
                along = rx * ux + ry * uy
                qx, qy = rx - along * ux, ry - along * uy
                rho2 = qx * qx + qy * qy + h2
                beyond = along - length
                mag = current * (along / sqrt(along * along + rho2)
                                 - beyond / sqrt(beyond * beyond + rho2)) / (4 * math.pi * rho2)
                bx += mag * uy
                by -= mag * ux
            lateral.append((bx * lx + by * ly) * h)
        return lateral


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
