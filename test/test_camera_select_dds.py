"""A leg steered by the rear camera alone while driving forwards, on a real graph over DDS.

The task `tape camera rear for 3 m` on a straight tape: communications parses the word,
comms_status and route_command carry it (msg_schemas), route following steers by the trailing
window (camera_select.py), and the task completes. Ground truth from /world/pose: the rear
window's centre, L_c behind the axle, keeps the tape inside its window all the way.
"""

from __future__ import annotations

import math
from pathlib import Path

from graph_probe import GraphProbe
import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]

L_C = 0.64  # m, turning.camera_ahead and the world's concic2.camera_distance
WINDOW_HOLD = 0.125 - 0.029  # m: the 58 mm tape stays inside the 0.25 m window
LEG = 3.0  # m


def straight_tape(tmp_path: Path) -> Path:
    """Write a 6 m straight tape along +x, the truck with both windows on it."""
    path = tmp_path / 'rear_straight.yaml'
    path.write_text('layout: rear_straight\nvehicle: concic2\nkind: tape\ntapes:\n'
                    '  - id: main\n    start: [0.0, 0.0, 0.0]\n    width: 0.058\n'
                    '    segments: [{straight: 6.0}]\nstart: {path: main, at: 1.6}\n')
    return path


@pytest.mark.timeout(300)
def test_a_rear_camera_leg_forwards_completes_over_dds(tmp_path: Path) -> None:
    g = GraphProbe(tmp_path / 'logs', layout=str(straight_tape(tmp_path)))
    try:
        g.start_task(f'tape camera rear for {LEG} m', cruise=0.3)
        g.report_with('completed', wall_limit=200)
        assert not any('FAILED' in r for r in g.reports), g.reports
        moving = [(a, b) for a, b in zip(g.path, g.path[1:], strict=False)
                  if math.dist(a[1:], b[1:]) > 0.005]
        assert moving, 'the truck never moved'
        off = []
        for (_t0, x0, y0), (_t1, x1, y1) in moving:
            h = math.atan2(y1 - y0, x1 - x0)
            off.append(abs(y1 - L_C * math.sin(h)))
        assert max(off) < WINDOW_HOLD, f'rear window {max(off) * 1000:.1f} mm off the tape'
        assert g.path[-1][1] - g.path[0][1] == pytest.approx(LEG, abs=0.05)
    finally:
        g.close()
    # route following said which camera steered the leg (its notes, in its log)
    said = ''.join(f.read_text() for f in (tmp_path / 'logs').glob('*route*.log'))
    assert 'leg 1: forward, rear camera trailing' in said, said[-2000:]
