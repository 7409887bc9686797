"""Camera calibration mode of the CONCIC-II, ROS-free (Rajagopalan 1991, App. F.3).

The thesis's calibration mode is for the camera, not the wheels: with the truck over the tape,
focus, aperture, exposure and lights are set for a clear picture, "the window size is measured
in order to provide a calibration that converts the number of pixels to a corresponding value
in mm", and "the console display shows the track width, position and orientation of the center
of the track image relative to the center line of the image window", to be checked "compared to
known values of the position and orientation" (App. F.3). Focus and lights have no counterpart
in the simulated camera; the rest is this mode.

Route following, in route_command mode calibration, holds the motors off and reads
calibration.frames frames of one camera (the front one, the rear one when route_command's
direction is reverse) through the same image analysis the guidance uses (camera_guidance.py).
It then reports, once, in words and in route_status: the window's scale (image.width / 128 and
image.depth / 64, mm per pixel across and along), and over the frames with a normal track the
track's width (the run length across the rows, times the scale, times cos eps_theta: across the
tape, not across the window), its position eps_d and orientation eps_theta (mean and spread),
and the width's difference from the known tape (calibration.tape_width). Frames without a
normal track (absent, a road sign's wide track, saturated) are counted by kind and left out; a
calibration that saw no normal track says so and reports no measurement.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
import math

import numpy as np

from agv_nodes.route_following.camera_guidance import ImageAnalyser, Validity
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.subsystem import Notes


@dataclass(frozen=True)
class CalibrationResult:
    """What one calibration measured (lengths in m, angles in rad)."""

    camera: str
    frames: int  # frames read
    normal: int  # of those, with a normal track (the ones measured)
    left_out: dict[str, int]  # frames without a normal track, by validity
    scale_across: float  # m per pixel across the window (column)
    scale_along: float  # m per pixel along travel (row)
    width: float = math.nan  # the tape's width across it
    width_error: float = math.nan  # width less the known tape width
    eps_d: float = math.nan  # mean position of the track, + = left of the window centre
    eps_d_spread: float = math.nan  # its standard deviation over the frames
    eps_theta: float = math.nan  # mean orientation, + = turned CCW
    eps_theta_spread: float = math.nan

    def text(self) -> str:
        """Return the console line (App. F.3's display), mm and degrees."""
        head = (f'calibration, {self.camera} camera, {self.frames} frame(s): scale '
                f'{self.scale_across * 1000:.3f} mm/px across, '
                f'{self.scale_along * 1000:.3f} mm/px along')
        left_out = ', '.join(f'{n} {kind}' for kind, n in sorted(self.left_out.items()))
        if not self.normal:
            return f'{head}; no normal track in any frame ({left_out})'
        return (f'{head}; track width {self.width * 1000:.1f} mm '
                f'({self.width_error * 1000:+.1f} mm from the known tape), position '
                f'{self.eps_d * 1000:+.1f} +- {self.eps_d_spread * 1000:.1f} mm, orientation '
                f'{math.degrees(self.eps_theta):+.2f} +- '
                f'{math.degrees(self.eps_theta_spread):.2f} deg'
                + (f'; left out {left_out}' if left_out else ''))


class Calibration:
    """See the module docstring; RouteCore hands it frames while in calibration mode."""

    def __init__(self, params: RouteParams, notes: Notes | None = None) -> None:
        self.p = params
        self.notes = notes or Notes()
        self.camera = ''  # the camera being read ('' = not calibrating)
        self.result: CalibrationResult | None = None  # the last calibration's
        self._analyser = ImageAnalyser(params.image)
        self._seen: Counter[str] = Counter()
        self._samples: list[tuple[float, float, float]] = []  # (width, eps_d, eps_theta)

    @property
    def running(self) -> bool:
        """Return whether a calibration is reading frames."""
        return bool(self.camera)

    def begin(self, camera: str, now: float) -> None:
        """Start reading `camera` ('front' or 'rear') afresh."""
        self.camera, self.result = camera, None
        self._analyser = ImageAnalyser(self.p.image)  # the normal width learnt anew
        self._seen, self._samples = Counter(), []
        self.notes.add(now, f'calibration: reading {self.p.calibration.frames} frame(s) of the '
                            f'{camera} camera')

    def stop(self) -> None:
        """Leave calibration mode (a result already made is kept)."""
        self.camera = ''

    def frame(self, frame: np.ndarray, now: float, camera: str) -> None:
        """Take a binary frame (1 = dark tape); the last one needed makes the result."""
        if camera != self.camera:
            return
        m = self._analyser.analyse(frame)
        self._seen[m.validity.value] += 1
        if m.validity is Validity.NORMAL:
            width = m.width_px * self._analyser.mm_col * math.cos(m.eps_theta)
            self._samples.append((width, m.eps_d, m.eps_theta))
        if sum(self._seen.values()) >= self.p.calibration.frames:
            self.result = self._result()
            self.notes.add(now, self.result.text(), 'info' if self.result.normal else 'warn')
            self.camera = ''

    def _result(self) -> CalibrationResult:
        scale = {'camera': self.camera, 'frames': sum(self._seen.values()),
                 'normal': len(self._samples),
                 'left_out': {k: n for k, n in self._seen.items() if k != 'normal'},
                 'scale_across': self._analyser.mm_col, 'scale_along': self._analyser.mm_row}
        if not self._samples:
            return CalibrationResult(**scale)
        width, eps_d, eps_theta = np.asarray(self._samples).T
        return CalibrationResult(
            **scale, width=float(width.mean()),
            width_error=float(width.mean()) - self.p.calibration.tape_width,
            eps_d=float(eps_d.mean()), eps_d_spread=float(eps_d.std()),
            eps_theta=float(eps_theta.mean()), eps_theta_spread=float(eps_theta.std()))
