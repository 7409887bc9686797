"""Dead reckoning along a stored trajectory, and each task's own camera law.

Rajagopalan 1991, App. F.9: the CONCIC-II drove a stored straight line, conic or polynomial
without the camera; App. F.5: identification-based guidance was a key away. Here a reckon task
(`reckon trajectory N for D m`, `reckon track for D m`) drives a dead-reckoning leg along a
stored trajectory placed at the truck's pose, or along the track it identified last, and a tape
task may choose its law (`tape with feed_forward ...`). The task language, the executive's
legs, the trajectories' geometry, and route following in lock step on the simulated world
(seeded; ground truth from the world's vehicle state).
"""

from __future__ import annotations

import math

import pytest
from test_route_feed_forward import L_A, MODELS, R, circle_floor, gap_floor, truck

from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.itinerary import itinerary
from agv_nodes.executive.tape_legs import TapeLegs
from agv_nodes.route_following.dead_reckoning import place, trajectory_conic
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.route_following.track_guidance import foot, tangent
from agv_nodes.settings import SettingError, build


def f(conic, x: float, y: float) -> float:
    A, B, C, D, E, F = conic
    return A * x * x + B * x * y + C * y * y + D * x + E * y + F


# -- the trajectories -----------------------------------------------------------------------------

@pytest.mark.parametrize('text, points', [
    ('line', [(0.0, 0.0), (2.0, 0.0), (-1.0, 0.0)]),
    ('arc 2.95 left', [(0.0, 0.0), (2.95, 2.95), (0.0, 5.9)]),
    ('arc 1.5 right', [(0.0, 0.0), (1.5, -1.5), (0.0, -3.0)]),
    ('polynomial 0.01 0.1 0.05', [(0.0, 0.01), (1.0, 0.16), (2.0, 0.41)]),
    ('conic 0 0 0 0 -2 0', [(0.0, 0.0), (3.0, 0.0)]),  # y = 0, given with the other sign
])
def test_a_stored_trajectory_is_its_curve_run_forwards(text: str, points) -> None:
    conic = trajectory_conic(text)
    for x, y in points:
        assert f(conic, x, y) == pytest.approx(0.0, abs=1e-12)
    assert tangent(conic, 0.0, points[0][1])[0] > 0.9  # forwards where the truck stands


@pytest.mark.parametrize('text, reason', [
    ('spiral', 'the shape must be one of'),
    ('arc 3', 'an arc is'),
    ('arc -3 left', 'the radius must be > 0'),
    ('line 2', 'line takes 0 number'),
    ('polynomial 0 x 1', 'not a number'),
    ('polynomial 0.2 0 0', 'passes 0.200 m from the truck'),
    ('conic 0 0 0 1 0 0', "crosses the truck's heading at 90 deg"),
])
def test_a_bad_trajectory_is_named_with_its_reason(text: str, reason: str) -> None:
    with pytest.raises(ValueError, match=reason) as err:
        trajectory_conic(text)
    assert repr(text) in str(err.value)
    with pytest.raises(SettingError) as bad:
        build(RouteParams, {'dead_reckoning.trajectories': ['line', text]})
    assert bad.value.name == 'dead_reckoning.trajectories' and reason in bad.value.reason


def test_placing_a_trajectory_at_the_truck_moves_and_turns_it() -> None:
    x0, y0, h = 1.5, -2.0, 2.3
    local = trajectory_conic('arc 2.95 left')
    placed = place(local, x0, y0, h)
    c, s = math.cos(h), math.sin(h)
    for phi in (0.0, 0.4, 1.9, 3.0):  # points of the circle about (0, R) in the leg frame
        u, v = R * math.sin(phi), R - R * math.cos(phi)
        x, y = x0 + c * u - s * v, y0 + s * u + c * v
        assert f(placed, x, y) == pytest.approx(0.0, abs=1e-9)
    along = tangent(placed, x0, y0)
    assert along == pytest.approx((c, s), abs=1e-12)  # forwards along the truck's heading
    assert foot(placed, x0 + 0.01 * s, y0 - 0.01 * c) == pytest.approx((x0, y0), abs=1e-4)


# -- the task language and the executive ----------------------------------------------------------

def test_reckon_and_tape_with_law_tasks_parse_into_the_record() -> None:
    task = parse_task('reckon trajectory 2 for 1.5 m').record()
    assert (task['op'], task['trajectory'], task['leg_distance']) == ('reckon', 2, 15)
    task = parse_task('reckon track for 1 m').record()
    assert (task['op'], task['trajectory'], task['leg_distance']) == ('reckon', 0, 10)
    task = parse_task('tape with feed_forward junctions 1 left for 5 m').record()
    assert (task['camera_law'], task['junction_1'], task['leg_distance']) == \
        ('feed_forward', 'left', 50)
    assert parse_task('tape').record()['camera_law'] == 'default'


@pytest.mark.parametrize('text, column, reason', [
    ('reckon for 2 m', 8, "expected 'trajectory' or 'track', got 'for'"),
    ('reckon trajectory 16 for 1 m', 19, 'trajectory 16 outside 1..15'),
    ('reckon track', 13, "expected 'for', got the end of the task"),
    ('tape with magic', 11, "expected 'feedback' or 'feed_forward', got 'magic'"),
])
def test_bad_reckon_and_law_tasks_name_the_column(text: str, column: int, reason: str) -> None:
    with pytest.raises(TaskError) as err:
        parse_task(text)
    assert (err.value.column, err.value.reason) == (column, reason)


def test_the_executive_runs_a_reckon_task_as_a_dead_reckoning_leg() -> None:
    task = parse_task('reckon trajectory 3 for 2 m').record()
    (step,) = itinerary(task)
    assert (step.kind, step.value) == ('reckon', 20)
    assert itinerary({**task, 'leg_distance': 0}) == []  # only its length ends it
    legs = TapeLegs(seed=1, rest_time=0.3)
    route = legs.start(task, 'reckon', 20, {'manoeuvre': 0})
    assert (route['mode'], route['trajectory'], route['direction']) == \
        ('dead_reckoning', 3, 'forward')
    outcome, route = legs.update({'leg': legs.leg, 'state': 'following', 'distance': 200},
                                 route, 5.0)
    assert outcome.state == 'running' and route['mode'] == 'idle'  # the motor-off stop
    tape = parse_task('tape with feed_forward then reverse').record()
    assert legs.start(tape, 'tape', 0, {})['camera_law'] == 'feed_forward'
    back = legs.start(tape, 'tape_reverse', 0, {})
    assert (back['camera_law'], back['trajectory']) == ('default', 0)


# -- route following in lock step -----------------------------------------------------------------

def casters_off(world, centre: tuple[float, float] = (0.0, 0.0)) -> float:
    """Return the worse caster contact's distance from the R = 2.95 m circle about `centre`, m."""
    s = world.vehicle.state
    c, n = math.cos(s.heading), math.sin(s.heading)
    return max(abs(math.hypot(s.x + k * L_A * c - centre[0], s.y + k * L_A * n - centre[1]) - R)
               for k in (1, -1))


@pytest.mark.timeout(240)
@pytest.mark.parametrize('model', MODELS)
def test_a_stored_arc_is_driven_without_the_camera(model: str) -> None:
    """Trajectory 2, `arc 2.95 left`, from where the truck stands on tape_1991's circle.

    The arc is tangent to the truck's heading at its axle centre; the truck stands with its
    window on the tape, 0.17 rad across it, so the arc is not the tape, and the camera is never
    looked at. After 5 m at 0.3 m/s (dead_reckoning.speed) both casters stay within 1 cm of
    the arc, the casters criterion of the feed-forward law.
    """
    h, world, route, script = truck(circle_floor(), model, 0.47, 'feedback',
                                    mode='dead_reckoning', trajectory=2)
    s = world.vehicle.state
    centre = (s.x - R * math.sin(s.heading), s.y + R * math.cos(s.heading))
    h.run(40.0, until=lambda: route.cam.travel >= 5.0)
    assert route.cam.travel >= 5.0 and script.states == ['following']
    assert route.cam.reckoning is not None and route.cam.measurement is not None
    worst = 0.0
    for _ in range(60):  # 3 s more, sampled each frame
        h.run(0.05)
        worst = max(worst, casters_off(world, centre))
    assert worst < 0.01, f'casters {worst * 1000:.1f} mm off the stored arc'
    assert route.track_guidance.circle.radius == pytest.approx(R, rel=1e-6)
    assert abs(route.speed - route.p.dead_reckoning.speed) < 0.01


@pytest.mark.timeout(240)
def test_a_missing_trajectory_stops_the_leg_at_once() -> None:
    h, world, route, script = truck(circle_floor(), 'kinematic', 0.47, 'feedback',
                                    mode='dead_reckoning', trajectory=9)
    h.run(1.0)
    assert script.states == ['no_track'] and not route.motor_on
    assert any('no trajectory 9 (3 stored)' in text for text in route.notes.texts())
    h, world, route, script = truck(circle_floor(), 'kinematic', 0.47, 'feedback',
                                    mode='dead_reckoning', trajectory=0)
    h.run(1.0)
    assert script.states == ['no_track']  # nothing identified yet to go along
    assert not route.motor_on


@pytest.mark.timeout(300)
@pytest.mark.parametrize('model', MODELS)
def test_a_tape_leg_with_feed_forward_then_the_identified_track_across_a_gap(model: str) -> None:
    """The task chooses feed_forward (the parameter says feedback); then reckon along its track.

    On the circle with 1 m of tape cut out 8 m along: leg 1 follows the tape with the
    feed-forward law the leg asked for, up to 0.2 m before the gap; leg 2 reckons along the
    identified track for 2.2 m, across the gap, both casters within 1 cm of where the tape
    would be over the first 1.5 m (1.5 cm by 2.2 m); leg 3 follows the tape again by camera,
    without a stop.
    """
    lay = gap_floor(at=8.0, gap=1.0)
    h, world, route, script = truck(lay, model, 0.47, 'feedback', camera_law='feed_forward')
    assert route.p.camera_law == 'feedback'
    # leg 1 from 0.5 m along: to 0.2 m before the gap (the window is L_c ahead of the axle)
    h.run(40.0, until=lambda: route.cam.travel >= 8.0 - 0.5 - 0.64 - 0.2)
    assert route.cam.law.feed_forward and route.cam.law.law == 'feed_forward'
    assert route.track_guidance.ready
    script.command.update(mode='dead_reckoning', trajectory=0, leg=2)
    worst = {1.5: 0.0, 2.2: 0.0}
    while (route.cam.leg != 2 or route.cam.travel < 2.2) and h.now < 60.0:
        h.run(0.05)
        span = 1.5 if route.cam.leg != 2 or route.cam.travel <= 1.5 else 2.2
        worst[span] = max(worst[span], casters_off(world))
    assert route.cam.reckoning is not None and route.cam.travel >= 2.2
    # The identified radius is within 1 % (the window's 3 m of samples), so the error grows
    # with the distance driven past the last sample: 4-8 mm at 1.5 m, 7-13 mm at 2.2 m.
    assert worst[1.5] < 0.01, f'casters {worst[1.5] * 1000:.1f} mm off in the first 1.5 m'
    assert worst[2.2] < 0.015, f'casters {worst[2.2] * 1000:.1f} mm off by 2.2 m'
    script.command.update(mode='camera', trajectory=0, leg=3, camera_law='feedback')
    h.run(8.0)
    assert 'no_track' not in script.states and route.cam.state == 'following'
    assert not route.cam.law.feed_forward and route.cam.law.law == 'lead'
    assert route.cam.travel > 2.0


def test_a_tape_layout_may_choose_the_law() -> None:
    """`camera_law` in a tape layout sets route following's default law; elsewhere refused."""
    from pathlib import Path
    import tempfile

    from agv_nodes.world.layout import LayoutError, layout_parameters, load_layout

    def layout(extra: str, kind: str = 'tape') -> Path:
        file = Path(tempfile.mkdtemp()) / 'law_test.yaml'
        group = 'tapes' if kind == 'tape' else 'wires'
        file.write_text(f'layout: law_test\nkind: {kind}\n{extra}{group}:\n  - id: main\n'
                        '    start: [0.0, 0.0, 0.0]\n    segments: [{straight: 5.0}]\n')
        return file

    lay = load_layout(layout('camera_law: feed_forward\n'))
    assert layout_parameters(lay)['route_following']['camera_law'] == 'feed_forward'
    assert 'camera_law' not in layout_parameters(load_layout(layout('')))['route_following']
    for extra, kind in (('camera_law: sideways\n', 'tape'), ('camera_law: feedback\n', 'wire')):
        file = layout(extra, kind)
        with pytest.raises(LayoutError) as err:
            load_layout(file)
        assert str(err.value).startswith(f'{file}: key camera_law: ')
