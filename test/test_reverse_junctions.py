"""Reverse legs of the CONCIC-II at junctions: a task's script applies in reverse too.

Lock step, the whole camera truck (world, route following, executive, communications) on the
default (dynamic) CONCIC-II model, the rear camera rendered. The script numbers the task's
junctions as its legs meet them (docs/tasks.md; the thesis's script file numbers a run's
junctions, Rajagopalan 1991, App. F.7), so `junctions 1 left, 2 ...` turns left at the forward
leg's one junction and decides the reverse leg's first one. Left and right are those of the
direction of travel (App. F.6 turns by the sign as met).

junction_1991: the main tape runs +x from the origin for 6 m, an R2 cross at x = 3 with 3 m
branches up (+y, left) and down (-y, right). The forward leg turns left up the left branch to its
end; the reverse leg backs down it, the rear window leading, and meets the main tape again, read
as R2 (left and right, the right branch straight on). Travelling -y, left of travel is +x and
right is -x. Each expected end comes from the layout's geometry: the leg ends where the tape it
follows ends, the rear window run past that end, the axle on the tape.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from agv_nodes.harness import Harness, submit, truck
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameters
from agv_nodes.world.layout import load_layout
from agv_nodes.world.settings import Concic2Params
from agv_nodes.world.tape_check import reverse_crossings


def default(cls: type, name: str) -> float:
    """Return a parameter's declared default (the parameter files, not the code under test)."""
    return next(p.default for p in parameters(cls) if p.name == name)


L_C = default(RouteParams, 'turning.camera_ahead')  # the window centre, m from the axle
# How far past a tape's end the leading window may stop: absent_frames frames of the longest
# camera cycle the thesis ran (200 ms, Rajagopalan 1991, 8.4.3) at cruise, then the motor-off
# coast from cruise.
CRUISE = default(RouteParams, 'camera_speed')
OVERRUN = (default(RouteParams, 'steering.absent_frames') * 0.2 * CRUISE
           + CRUISE ** 2 / (2.0 * default(Concic2Params, 'coast_deceleration')))


def run_task(layout: str, text: str, seconds: float = 150.0) -> Harness:
    h = truck(layout, overrides={'world': {'rear_camera': True}})
    ex = h.cores['executive']
    h.run(0.5)
    submit(h, text)
    assert h.run(seconds, until=lambda: ex.report['state'] in ('completed', 'failed'))
    h.run(1.0)  # to rest
    return h


def ended_on(h: Harness, tape: str, at_end: bool) -> None:
    """Assert the reverse leg ended where `tape` ends, followed toward that end, at rest.

    `at_end`: toward the tape's end (else toward its start).
    """
    lay, s = h.world.layout, h.world.vehicle.state
    path = lay.paths[tape]
    along, off, heading = path.project(s.x, s.y)
    travel = heading if at_end else heading + math.pi  # the direction of travel along it
    # In reverse the body points against travel.
    body_off = math.degrees(math.atan2(math.sin(s.heading - travel - math.pi),
                                       math.cos(s.heading - travel - math.pi)))
    assert abs(off) < 0.01 and abs(body_off) < 3.0, (tape, s.x, s.y, math.degrees(s.heading))
    rear = along + L_C if at_end else along - L_C  # the rear window, along the tape
    past = rear - path.length if at_end else -rear
    assert 0.0 < past < OVERRUN, (tape, along, past, OVERRUN)
    assert abs(s.speed) < 1e-3 and not h.world.vehicle.enable


@pytest.mark.timeout(400)
@pytest.mark.parametrize(('decision', 'tape', 'at_end'), [
    ('', 'sign0_right', True),  # no decision: straight across, onto the right branch to its end
    (', 2 left', 'main', True),  # left of travel (-y) is +x: backing on to the main tape's end
    (', 2 right', 'main', False),  # right of travel is -x: backing to where the tape begins
])
def test_a_scripted_decision_is_taken_in_reverse_at_the_crossing_met_backwards(
        decision: str, tape: str, at_end: bool) -> None:
    h = run_task('junction_1991', f'tape junctions 1 left{decision} then reverse')
    ex = h.cores['executive']
    assert ex.report['state'] == 'completed', (ex.report, ex.notes.texts())
    assert h.cores['route_following'].cam.junctions == 1  # the reverse leg met one junction
    taken = decision.split()[-1] if decision else 'straight'
    assert any(f'junction 2 met ({taken})' in t for t in ex.notes.texts()), ex.notes.texts()
    ended_on(h, tape, at_end)


CORNER = """\
layout: corner_1991
description: a tape ending at a P11 corner, its left branch 3 m
vehicle: concic2
kind: tape
tapes:
  - id: main
    start: [0.0, 0.0, 0.0]
    width: 0.058
    segments:
      - {straight: 3.029}
signs:
  - {type: P11, path: main, at: end, branch: 3.0}
start: {path: main, at: 0.3}
"""


@pytest.mark.timeout(300)
def test_a_reverse_decision_the_sign_cannot_honour_fails_naming_it(tmp_path: Path) -> None:
    """Back down a P11 corner's branch: the main tape lies only to the right of travel.

    Travelling -y down the left branch, the main tape (which ends at the corner) runs off to -x,
    the right of travel: the rear window reads a P12 (right alone). A scripted left there is not
    on it: the truck stops short of the crossing, motors off, and the executive's line names the
    junction (the task's 2nd), the sign, what it offers and the decision.
    """
    (tmp_path / 'corner_1991.yaml').write_text(CORNER)
    h = run_task(str(tmp_path / 'corner_1991.yaml'), 'tape junctions 1 left, 2 left then reverse')
    ex, s = h.cores['executive'], h.world.vehicle.state
    assert (ex.report['state'], ex.report['cause'], ex.report['subsystem']) == \
        ('failed', 'no_branch', 'route'), ex.report
    assert any('FAILED no_branch (route): junction 2: sign P12 seen, offering right; the '
               'decision left is not on it' in t for t in ex.notes.texts()), ex.notes.texts()
    assert h.cores['communications'].results[-1][1:] == ('failed', 'no_branch')
    assert any(': FAILED: no branch (route): junction 2: sign P12 seen, offering right; the '
               'decision left is not on it' in t
               for t in h.cores['communications'].notes.texts()), \
        h.cores['communications'].notes.texts()
    corner = load_layout(tmp_path / 'corner_1991.yaml')
    # agv-layout check foretold the reading: backing out of the branch, a P12, right alone.
    assert 'read as P12: no decision goes straight across and off the tape' in \
        reverse_crossings(corner)[0]
    crossing = corner.signs[0]['at']
    # On the branch (x = the crossing), stopped short of the main tape (y = 0), at rest.
    assert abs(s.x - crossing) < 0.01 and 0.0 < s.y < 3.0, (s.x, s.y)
    assert abs(s.speed) < 1e-3 and not h.world.vehicle.enable
