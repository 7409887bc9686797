"""A scripted decision taken in reverse over DDS: the camera truck's graph, one process a node.

On junction_1991 (main tape +x from the origin for 6 m, an R2 cross at x = 3 with 3 m branches
at right angles) the task turns left at the cross (junction 1), follows the branch to its end,
then backs down it with the rear camera leading and, at the cross met backwards (the task's
junction 2: the script numbers the task's junctions as its legs meet them, docs/tasks.md),
turns left of travel: travelling -y, that is +x, so it backs along the main tape to its end.
Ground truth (/world/pose) shows where it went; the same task in lock step is
test/test_reverse_junctions.py.
"""

from __future__ import annotations

from graph_probe import GraphProbe
import pytest

from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameters
from agv_nodes.world.settings import Concic2Params

pytestmark = [pytest.mark.dds, pytest.mark.slow]


def default(cls: type, name: str) -> float:
    """Return a parameter's declared default (the parameter files, not the code under test)."""
    return next(p.default for p in parameters(cls) if p.name == name)


CROSS_X, MAIN_END = 3.0, 6.0  # config/layouts/junction_1991.yaml
L_C = default(RouteParams, 'turning.camera_ahead')
CRUISE = default(RouteParams, 'camera_speed')
# The leading window stops past a tape's end by at most absent_frames frames of the longest
# camera cycle (200 ms, Rajagopalan 1991, 8.4.3) at cruise and the motor-off coast from cruise.
OVERRUN = (default(RouteParams, 'steering.absent_frames') * 0.2 * CRUISE
           + CRUISE ** 2 / (2.0 * default(Concic2Params, 'coast_deceleration')))


@pytest.mark.timeout(300)
def test_a_reverse_leg_turns_left_of_travel_at_the_cross_as_scripted(tmp_path) -> None:
    g = GraphProbe(tmp_path / 'logs', layout='junction_1991')
    try:
        g.start_task('tape junctions 1 left, 2 left then reverse', cruise=0.3)
        g.report_with('completed', wall_limit=240)
        assert not any('FAILED' in r for r in g.reports), g.reports
        # Forward: up the left branch (x = 3) nearly to its end.
        far = max(g.path, key=lambda p: p[2])
        assert abs(far[1] - CROSS_X) < 0.03 and far[2] > 2.0, far
        # Reverse: back down to the cross, then along the main tape toward +x (the body
        # pointing -x), the rear window, L_c behind the axle, run past the tape's end at x = 6.
        after = [p for p in g.path if p[0] > far[0]]
        back_at_cross = next(p for p in after if abs(p[2]) < 0.02)
        assert abs(back_at_cross[1] - CROSS_X) < 0.03, back_at_cross
        end = g.path[-1]
        assert abs(end[2]) < 0.01, f'ended {end[2]:.3f} m off the main tape'
        past = end[1] + L_C - MAIN_END
        assert 0.0 < past < OVERRUN, f'the rear window stopped {past:.3f} m past the end'
    finally:
        g.close()
