"""Binary camera (Rajagopalan 1991 ch 4, 6.3.4): a 64 x 128 window of the floor.

The window is 50 mm along travel by 250 mm across, thresholded by the optic-RAM itself (dark tape =
1); row 0 is its leading edge, column 0 its left edge (4.2). A pixel is dark within half the tape
width of a tape centreline, and not past a tape's square-cut end; random specks (dark runs shorter
than the noise filter) model dirt and pixel differences. The rear camera is the same window at
-L_c, facing backwards.
"""

import math

import numpy as np

from agv_nodes.world.layout import Path2D
from agv_nodes.world.settings import CameraParams

ROWS, COLS = 64, 128


class BinaryCamera:
    """Renders binary frames of the tape for a window pose."""

    def __init__(self, params: CameraParams, tapes: list[Path2D], rng: np.random.Generator):
        self.p = params
        self.tapes = tapes
        self.rng = rng
        # Pixel centres in window coordinates: along (+ ahead) and lateral (+ left).
        self.along = (0.5 - (np.arange(ROWS) + 0.5) / ROWS) * params.depth  # row 0 ahead
        self.lateral = (0.5 - (np.arange(COLS) + 0.5) / COLS) * params.width  # col 0 left

    def render(self, cx: float, cy: float, heading: float, noise: bool = True) -> np.ndarray:
        """Return a (64, 128) uint8 frame (1 = dark) for a window centred at (cx, cy)."""
        fx, fy = math.cos(heading), math.sin(heading)
        lx, ly = -fy, fx
        gx = cx + self.along[:, None] * fx + self.lateral[None, :] * lx
        gy = cy + self.along[:, None] * fy + self.lateral[None, :] * ly
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        dark = np.zeros(len(pts), dtype=bool)
        for tape in self.tapes:
            # Only segments that can reach the window (half-diagonal + tape + one segment).
            reach = 0.5 * math.hypot(self.p.depth, self.p.width) + tape.width + 0.05
            near = np.hypot(tape.points[:, 0] - cx, tape.points[:, 1] - cy) < reach
            idx = np.flatnonzero(near[:-1] | near[1:])
            if idx.size == 0:
                continue
            idx = self._crossing(tape, idx, cx, cy, fx, fy)
            if idx.size == 0:
                continue
            a = tape.points[idx]
            d = tape.points[idx + 1] - a
            dd = np.einsum('ij,ij->i', d, d)
            rx = pts[:, 0:1] - a[None, :, 0]  # (pixels, segments)
            ry = pts[:, 1:2] - a[None, :, 1]
            along = (rx * d[:, 0] + ry * d[:, 1]) / np.where(dd > 0, dd, 1.0)
            t = np.clip(along, 0.0, 1.0)
            ex, ey = rx - t * d[:, 0], ry - t * d[:, 1]
            dist2 = ex * ex + ey * ey
            on = dist2.min(axis=1) <= (tape.width / 2.0) ** 2
            if any(tape.square_ends):
                on &= ~self._past_square_end(tape, idx, dist2, along)
            dark |= on
        frame = dark.reshape(ROWS, COLS).astype(np.uint8)
        if noise and self.p.specks:
            for _ in range(self.p.specks):
                r = int(self.rng.integers(0, ROWS))
                c = int(self.rng.integers(0, COLS))
                n = int(self.rng.integers(1, self.p.speck_max + 1))
                frame[r, c:c + n] = 1
        return frame

    def _crossing(self, tape: Path2D, idx: np.ndarray, cx: float, cy: float, fx: float,
                  fy: float) -> np.ndarray:
        """Return the segments of `idx` whose box meets the window grown by half the tape.

        Only those can come within half a tape width of a pixel, so the frame is the same as
        with every near segment (the nearest segment of a dark pixel is always among them), at
        a quarter of the work: the window is 50 mm deep and the tape's points 20 mm apart.
        """
        a, b = tape.points[idx], tape.points[idx + 1]
        margin = tape.width / 2.0 + 1e-9
        hu, hv = self.p.depth / 2.0 + margin, self.p.width / 2.0 + margin
        keep = np.ones(len(idx), dtype=bool)
        for ex, ey, half in ((fx, fy, hu), (-fy, fx, hv)):  # along travel, then across
            ua = (a[:, 0] - cx) * ex + (a[:, 1] - cy) * ey
            ub = (b[:, 0] - cx) * ex + (b[:, 1] - cy) * ey
            keep &= (np.maximum(ua, ub) >= -half) & (np.minimum(ua, ub) <= half)
        return idx[keep]

    @staticmethod
    def _past_square_end(tape: Path2D, idx: np.ndarray, dist2: np.ndarray,
                         along: np.ndarray) -> np.ndarray:
        """Return the pixels beyond a square-cut end of `tape` (nearest its end segment).

        A tape cut square at a junction (a road sign at a tape's end, a sign's patch) shows no
        rounded cap past the cut: the camera would see it as a short normal-width track after
        the branches and raise the straight flag (Rajagopalan 1991, 4.3).
        """
        col = dist2.argmin(axis=1)
        nearest = idx[col]
        rows = np.arange(len(nearest))
        past = np.zeros(len(nearest), dtype=bool)
        if tape.square_ends[0]:
            past |= (nearest == 0) & (along[rows, col] < 0.0)
        if tape.square_ends[1]:
            past |= (nearest == len(tape.points) - 2) & (along[rows, col] > 1.0)
        return past

    def truth(self, cx: float, cy: float, heading: float) -> tuple[float, float] | None:
        """Return (eps_d, eps_theta) of the nearest tape at the window centre (Rajagopalan 5.2)."""
        best = None
        for tape in self.tapes:
            s, lateral, tangent = tape.project(cx, cy)
            if best is None or abs(lateral) < abs(best[0]):
                # Track to the left of the window centre => eps_d > 0.
                best = (-lateral, math.atan2(math.sin(tangent - heading),
                                             math.cos(tangent - heading)))
        return best
