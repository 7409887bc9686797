"""The tape floor's layout check agrees with the camera truck: the bends it warns of, it misses.

agv_nodes.world.tape_check derives the smallest radius the CONCIC-II can follow from its
geometry (the window L_c ahead of the axle, the caster angle limit, the road-sign width test);
`agv-layout check` warns of every tighter bend. Each room here, a straight lead-in and a 200 deg
bend of one radius, is driven by the whole lock-step truck (world, route following, executive,
communications; the default dynamic model, default speeds) with `tape for D m` past the bend.
Followed means: the task completed and the window read no road sign on the plain tape. That
truth is set beside the check's verdict, on either side of the limit: below the caster limit
(the truck loses the tape), between it and the road-sign limit (it reads a sign on plain tape),
and above both.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from agv_nodes.harness import submit, truck
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameters
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.layout_check import check_layout
from agv_nodes.world.layout_cli import main as agv_layout
from agv_nodes.world.tape_check import smallest_radius

LEAD_IN, BEND = 2.0, 200.0  # m of straight tape, then the bend's degrees


def default(name: str) -> float:
    """Return a route-following parameter's declared default (the parameter file)."""
    return next(p.default for p in parameters(RouteParams) if p.name == name)


def limits() -> tuple[float, float]:
    """Return the two limits, written apart from tape_check, from the declared defaults.

    Window on the tape of a circle R, axle on a concentric circle r_a: R^2 = r_a^2 + L_c^2, and
    the tape crosses the window at asin(L_c / R) to travel. Caster: r_a >= L_ae / tan(max)
    (Rajagopalan 1991, Eq. 5.10-5.11). Road sign: a row cuts w / cos(angle), wide beyond
    wide_factor x w (4.3).
    """
    ahead, top = default('turning.camera_ahead'), default('steering.max_angle')
    lae = default('steering.caster_distance') + default('steering.caster_trail') * (
        1 - math.cos(top))
    caster = math.sqrt(ahead ** 2 + (lae / math.tan(top)) ** 2)
    wide = ahead / math.sin(math.acos(1.0 / default('image.wide_factor')))
    return caster, wide


def room(tmp_path: Path, radius: float) -> Path:
    name = f'bend_{round(radius * 1000)}'
    file = tmp_path / f'{name}.yaml'
    file.write_text(f'layout: {name}\nvehicle: concic2\nkind: tape\ntapes:\n  - id: main\n'
                    '    start: [0.0, 0.0, 0.0]\n    width: 0.058\n    segments:\n'
                    f'      - {{straight: {LEAD_IN}}}\n      - {{arc: {radius}, angle: {BEND}}}\n'
                    '      - {straight: 2.0}\nstart: {path: main, at: 0.3}\n')
    return file


@pytest.mark.timeout(30)
def test_the_smallest_radius_is_the_geometrys() -> None:
    caster, wide = limits()
    radius, why = smallest_radius()
    assert radius == pytest.approx(max(caster, wide), abs=1e-9)
    assert (round(caster, 3), round(wide, 3)) == (0.669, 0.953)  # the defaults: the sign binds
    assert 'road sign' in why


@pytest.mark.timeout(600)
@pytest.mark.parametrize('radius', [0.6, 0.85, 1.05])
def test_the_check_warns_of_exactly_the_bends_the_truck_cannot_follow(tmp_path, radius) -> None:
    caster, wide = limits()
    file = room(tmp_path, radius)
    warned = [w for w in check_layout(load_layout(file)).warnings() if 'a bend of R' in w]
    h = truck(str(file))
    ex, route = h.cores['executive'], h.cores['route_following']
    h.run(0.5)
    length = round(LEAD_IN - 0.3 + radius * math.radians(BEND) + 1.0, 1)
    submit(h, f'tape for {length} m')
    assert h.run(120.0, until=lambda: ex.report['state'] in ('completed', 'failed'))
    followed = ex.report['state'] == 'completed' and route.cam.junctions == 0
    assert followed == (not warned), (radius, ex.report, route.cam.junctions, warned)
    assert followed == (radius >= max(caster, wide))
    if radius < caster:  # the caster angle cannot turn it tight enough: the tape is lost
        assert (ex.report['state'], ex.report['cause']) == ('failed', 'lost_track'), ex.report
    elif not followed:  # the tape crosses the window wide: a road sign read on plain tape
        assert ex.report['state'] == 'completed' and route.cam.junctions >= 1
    if warned:
        assert len(warned) == 1 and f'R {radius:.2f} m' in warned[0] and str(file) in warned[0]


@pytest.mark.timeout(60)
def test_agv_layout_check_names_the_bend_and_each_crossing_a_reverse_leg_meets(
        tmp_path, capsys) -> None:
    file = room(tmp_path, 0.85)
    assert agv_layout(['check', str(file), 'junction_1991']) == 0  # warnings, not errors
    err = capsys.readouterr().err.strip().splitlines()
    assert [line.split(': ')[1] for line in err] == [
        "tape 'main'", "a reverse leg backing out of sign 1 (R2 on main)'s left branch "
        'sign0_left meets the crossing at (3.00, 0.00) read as R2',
        "a reverse leg backing out of sign 1 (R2 on main)'s right branch sign0_right meets "
        'the crossing at (3.00, 0.00) read as R2'], err
    # junction_1991: an R2 at x = 3 with 3 m branches up (left) and down (right), the main tape
    # 6 m along +x. Backing down the left branch, travel is -y: left of it +x (on to the main
    # tape's end), right -x, straight on the other branch; test_reverse_junctions.py drives it.
    assert err[1].endswith('no decision goes straight across onto sign0_right toward its end; '
                           'left of travel: along main toward its end; right of travel: along '
                           'main toward its start'), err[1]
    shipped = check_layout(load_layout(layout_path('signs_1991')))
    assert shipped.warnings() == [] and len(shipped.reverse) == 11  # its 11 turning branches


@pytest.mark.timeout(30)
def test_agv_demo_warns_of_a_tight_bend_in_a_room_of_ones_own_and_runs(
        tmp_path, capsys, monkeypatch) -> None:
    from agv_nodes import demo

    monkeypatch.setattr(demo, 'run', lambda args: 0)
    tight, wide = room(tmp_path, 0.85), room(tmp_path, 1.05)
    assert demo.main(['--truck', 'concic2', '--layout', str(tight)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'agv-demo: warning: layout {tight}: ') \
        and 'R 0.85 m' in err[0], err
    assert demo.main(['--truck', 'concic2', '--layout', str(wide)]) == 0
    assert capsys.readouterr().err == ''
