"""The camera truck with our curve settings on curvature that changes, by the world's truth.

The goals are the issue's: on S-bends of R 2-3 m arcs joined by straights under 1 m, at
0.31-0.79 m/s, the camera window's peak error on every arc at most 15 mm; on circles of R 2.0-3.0
m a steady error (mean, 20-30 s) at most 2 mm. The cases are the worst of
bench/results/concic2_curvature_bench.md: the fastest speed, the shortest straight, the
tighter arc last, on the dynamic model (Huang's, App. G, whose wheels lag most), and the
tightest circle. Errors are ground truth from the world (the window centre's distance from the
tape as laid), never the controller's own estimate; the runs are seeded, in lock step.
"""

from __future__ import annotations

import math
from pathlib import Path
import sys

import pytest

from agv_nodes.route_following.camera_guidance import WindowPredictor
from agv_nodes.route_following.settings import SteeringParams

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bench'))
import concic2_curvature_bench as bench  # noqa: E402

OURS = bench.LAWS['ours']  # our curve settings (not the defaults: the road signs, see the bench)
PEAK, STEADY = 15.0, 2.0  # mm, the goals


@pytest.mark.timeout(30)
def test_predictor_reads_the_curvature_under_the_window() -> None:
    """A truck running straight over tape of curvature 0.4 /m: the tape turns under the window.

    Driving straight (no angle asked, so no yaw), the tape's angle in the window grows by
    kappa v per second; 0.15 s on it is 0.15 kappa v more, and the window has moved across it
    by v sin(alpha) per second meanwhile.
    """
    kappa, v, dt = 0.4, 0.5, 0.05
    predictor = WindowPredictor(SteeringParams(predict=0.15), 0.64)
    for k in range(60):
        alpha = kappa * v * k * dt
        eps_d, eps_theta = predictor.predict(0.0, alpha, dt, v)
    assert predictor.kappa == pytest.approx(kappa, rel=1e-3)
    assert eps_theta == pytest.approx(alpha + 0.15 * kappa * v, rel=1e-3)
    assert eps_d == pytest.approx(0.15 * v * math.sin(alpha + 0.075 * kappa * v), rel=1e-3)
    off = WindowPredictor(SteeringParams(predict=0.0), 0.64)
    assert off.predict(0.01, 0.02, dt, v) == (0.01, 0.02)  # predict 0: as measured


@pytest.mark.timeout(300)
@pytest.mark.parametrize('model', ['kinematic', 'dynamic'])
def test_s_bend_peak_per_arc(model: str) -> None:
    """R 3.0 m left, 0.3 m of straight, R 2.0 m right at 0.79 m/s: each arc's peak <= 15 mm."""
    peaks = bench.bend(3.0, 0.3, 2.0, model, 0.79, OURS)
    assert peaks is not None, 'the tape left the window: motor-off stop'
    assert max(peaks) <= PEAK, peaks


@pytest.mark.timeout(300)
def test_s_bend_other_order() -> None:
    """R 2.0 m left, 0.3 m of straight, R 3.0 m right at 0.79 m/s on the dynamic model."""
    peaks = bench.bend(2.0, 0.3, 3.0, 'dynamic', 0.79, OURS)
    assert peaks is not None, 'the tape left the window: motor-off stop'
    assert max(peaks) <= PEAK, peaks


@pytest.mark.timeout(300)
@pytest.mark.parametrize('speed', [0.31, 0.79])
def test_circle_r2_steady(speed: float) -> None:
    """The R 2.0 m circle on the dynamic model: mean |error| from 20 s to 30 s <= 2 mm."""
    got = bench.circle(2.0, 'dynamic', speed, OURS)
    assert got is not None, 'the tape left the window: motor-off stop'
    assert got[0] <= STEADY, got


@pytest.mark.timeout(300)
def test_thesis_law_misses_the_goal_there() -> None:
    """The same S-bend under the thesis preset's law: the course tells the laws apart."""
    peaks = bench.bend(3.0, 0.3, 2.0, 'dynamic', 0.79, bench.LAWS['thesis'])
    assert peaks is None or max(peaks) > PEAK, peaks
