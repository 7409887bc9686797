"""The approach to a junction's crossing and the quarter turn (Rajagopalan 1991, App. F.6).

Where the tape ends at the sign (P11, P12, R1) the leading window runs past its end before the
axle reaches the crossing; its last frames show one branch alone. Steered from them, the truck
came to the crossing 10-20 deg off and the quarter turn left the window beside the branch
(lost_track at north_c's R1). The approach now follows the tape's line as the plain frames
before the sign gave it, by wheel odometry, and the spin turns from that line. On the dynamic
model the spin's stopping profile hunted about its end behind the LM628 loops (+-2.7 deg, never
at rest within the angle tolerance) until the turn timed out: it now ends linearly.
"""

from __future__ import annotations

from collections.abc import Callable
import math

import pytest

from agv_nodes.harness import CONCIC2_QUICK, Harness, submit, truck
from agv_nodes.odometry import Odometer
from agv_nodes.route_following.junction_turn import TapeLine
from agv_nodes.route_following.settings import RouteParams

CHORD = 'tape junctions 1 left, 2 right, 3 left, 4 left for 16 m'  # R2, P12, P11, R1


def _run(h: Harness, text: str, limit: float = 200.0,
         each: Callable[[], None] = lambda: None) -> dict:
    """Hand `text` to the truck and run it to its report (`each` after every step)."""
    ex = h.cores['executive']
    h.run(0.5)
    submit(h, text)
    h.run(0.2)

    def done() -> bool:
        each()
        return ex.mode in ('idle', 'failed') and \
            ex.report['state'] in ('completed', 'failed', 'rejected')

    h.run(limit, until=done)
    return dict(ex.report)


def _heading_error(heading: float, tape: float) -> float:
    """Degrees between two headings (rad), wrapped to +-180."""
    return math.degrees((heading - tape + math.pi) % (2.0 * math.pi) - math.pi)


@pytest.mark.timeout(240)
def test_the_chord_turns_at_every_tape_end_and_ends_on_the_upper_straight() -> None:
    # From the layout's start: R2 left up north_a, P12 right onto east_b, P11 left onto
    # north_c, R1 left onto the upper straight (run westwards). Steered by the frames to the
    # crossing it came to R1 23 deg off and lost the tape after the spin.
    h = truck('signs_1991', seed=1, overrides={'world': {'concic2.model': 'kinematic'}})
    turns: list[float] = []
    cam = h.cores['route_following'].cam
    was = ''

    def watch() -> None:
        nonlocal was
        if was in ('spin', 'settle') and not cam.turn.phase:
            turns.append(h.world.pose()[2])
        was = cam.turn.phase

    report = _run(h, CHORD, each=watch)
    assert report['state'] == 'completed', report
    x, y, heading, _speed = h.world.pose()
    assert abs(y - 2.95) < 0.05 and 0.0 < x < 4.0  # on the upper straight, west of north_c
    assert abs(h.world.nearest_path_offset(x, y)) < 0.015  # on the tape by ground truth
    assert abs(_heading_error(heading, math.pi)) < 5.0
    # Each quarter turn ends square to its branch: north, east, north, west.
    assert len(turns) == 4
    for heading, tape in zip(turns, (90.0, 0.0, 90.0, 180.0), strict=True):
        assert abs(_heading_error(heading, math.radians(tape))) < 2.0, (turns, tape)


@pytest.mark.timeout(120)
def test_the_quick_programme_turns_and_reverses_on_the_dynamic_model() -> None:
    # R2 right into the bay, its P21 straight on to the tape's end, then 5 m back out across
    # the loop onto north_a, the rear camera leading: the spin at R2 used to hunt about its end
    # until the turn timed out.
    h = truck('signs_1991', seed=1, overrides={'world': {'concic2.model': 'dynamic'}})
    (task,) = CONCIC2_QUICK
    report = _run(h, task, limit=60.0)
    assert report['state'] == 'completed', report
    x, y, _heading, _speed = h.world.pose()
    assert abs(x - 1.0) < 0.015 and -2.9 < y < 0.0  # on north_a
    assert abs(h.world.nearest_path_offset(x, y)) < 0.015
    assert h.now < 45.0


@pytest.mark.timeout(10)
@pytest.mark.parametrize('direction', [1, -1])
def test_the_tape_line_is_placed_by_odometry_in_the_frame_of_travel(direction: int) -> None:
    # Drive straight 0.5 m at 2 deg left of a tape that runs along x, 10 mm to the right of
    # the start: the frames place the tape's points, the line comes out along the tape.
    p = RouteParams()
    odo, line = Odometer(), TapeLine(p)
    line.reset(odo, direction)
    slant = math.radians(2.0)
    for i in range(1, 51):
        along = 0.01 * i
        odo.left = odo.right = direction * along
        ahead = along + p.turning.camera_ahead
        # the tape (y = -0.01) seen from a window at `ahead` along the slanted heading
        window_y = ahead * math.sin(slant)
        line.saw((-0.01 - window_y) * math.cos(slant), odo)
    fit = line.fit()
    assert fit is not None
    lx, ly, heading = fit
    assert abs(heading + slant) < math.radians(0.1)  # the tape, seen from the start's heading
    assert abs(lx * math.sin(slant) + ly * math.cos(slant) + 0.01) < 0.001  # y = -0.01 on it
    # the window is left of the tape: the line's offset is negative (eps_d's sense)
    assert line.offset(fit) < 0.0
