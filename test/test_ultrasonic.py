"""System 13's ultrasonic sensor (Rajagopalan 1991, 6.3.11): the sonar model, obstacles, the stop.

The sonar's first echoes are checked against a model written apart (the disc sampled on a fine
polar grid, the nearest sample inside the cone), and its limits against the declared parameters
(Rajagopalan 1991, 2.2.4.4: 27.5 cm to 12 m). The obstacle stop's rules are driven reading by
reading. In lock step the whole camera truck (world, route following, executive,
communications) drives a straight tape; an obstacle is placed ahead while it runs: it stops short
by the world's ground truth within the band the parameters give, stays stopped, and once the
obstacle is removed sets off again and finishes its leg; a sonar that goes silent stops it and
fails the task naming the fault.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import statistics

import pytest
from tape_floors import straight_tape

from agv_nodes.harness import Harness, submit, truck
from agv_nodes.route_following.obstacle_stop import ObstacleStop
from agv_nodes.route_following.settings import ObstacleStopParams, RouteParams
from agv_nodes.settings import parameters
from agv_nodes.subsystem import Notes
from agv_nodes.world.layout import LayoutError, load_layout
from agv_nodes.world.obstacles import Obstacle, ObstacleCommands, Obstacles
from agv_nodes.world.settings import Concic2Params, SonarParams, WorldParams
from agv_nodes.world.sonar import Sonar, disc_echo

pytestmark = pytest.mark.timeout(240)


def default(cls: type, name: str) -> float:
    """Return a parameter's declared default (the parameter files, not the code under test)."""
    return next(p.default for p in parameters(cls) if p.name == name)


# -- the sonar model --------------------------------------------------------------------------
def sampled_echo(sx: float, sy: float, heading: float, half: float, cx: float, cy: float,
                 r: float, n: int = 600) -> float | None:
    """Return the nearest point of the disc inside the cone, the disc sampled (a model apart)."""
    best = None
    for i in range(n + 1):
        rho = r * i / n
        for k in range(n):
            phi = 2 * math.pi * k / n
            x, y = cx + rho * math.cos(phi) - sx, cy + rho * math.sin(phi) - sy
            off = math.atan2(y, x) - heading
            if abs(math.atan2(math.sin(off), math.cos(off))) <= half:
                d = math.hypot(x, y)
                best = d if best is None else min(best, d)
    return best


@pytest.mark.parametrize('cx, cy, r, heading', [
    (2.0, 0.0, 0.10, 0.0),  # straight ahead: the centre distance less the radius
    (2.0, 0.70, 0.20, 0.0),  # centre outside the 15 deg half-cone, its edge inside it
    (2.0, -0.70, 0.20, 0.0),  # the same on the other side
    (-1.0, 3.0, 0.40, 1.7),  # another heading, across the edge ray
    (3.0, 1.5, 0.20, 0.0),  # wholly outside the cone
    (-2.0, 0.0, 0.50, 0.0),  # behind
])
def test_first_echo_is_the_nearest_point_of_the_disc_in_the_cone(cx, cy, r, heading) -> None:
    half = math.radians(15.0)
    got = disc_echo(0.0, 0.0, heading, half, cx, cy, r)
    want = sampled_echo(0.0, 0.0, heading, half, cx, cy, r)
    if want is None:
        assert got is None
    else:  # the grid's spacing (2 pi r / 600 around, r / 600 across) bounds the sampled one
        assert got is not None and 0.0 <= want - got <= 2 * math.pi * r / 600 + 1e-9


def test_the_ranges_and_the_mounting_are_the_declared_ones() -> None:
    p = WorldParams().sonar
    mount, near, far = (default(SonarParams, k) for k in ('mount', 'min_range', 'max_range'))
    assert (near, far) == (0.275, 12.0)  # Rajagopalan 1991, 2.2.4.4: the Polaroid sensor
    sonar = Sonar(p, seed=1)

    def at(d: float) -> list[Obstacle]:  # the surface d ahead of the sensor
        return [Obstacle('o', mount + d + 0.1, 0.0, 0.2)]

    assert sonar.first_echo(0.0, 0.0, 0.0, at(2.0)) == pytest.approx(2.0, abs=1e-12)
    assert sonar.ping(0.0, 0.0, 0.0, at(near - 0.01)) == -math.inf  # too near to time
    assert sonar.ping(0.0, 0.0, 0.0, at(far + 0.01)) == math.inf  # beyond its reach
    assert sonar.ping(0.0, 0.0, 0.0, []) == math.inf


def test_readings_carry_the_declared_noise_and_repeat_with_the_seed() -> None:
    p, noise = WorldParams().sonar, default(SonarParams, 'noise')
    items = [Obstacle('o', 3.0, 0.0, 0.2)]
    truth = 3.0 - 0.1 - default(SonarParams, 'mount')
    sonar = Sonar(p, seed=7)
    pings = [sonar.ping(0.0, 0.0, 0.0, items) for _ in range(4000)]
    again = Sonar(p, seed=7)
    assert [again.ping(0.0, 0.0, 0.0, items) for _ in range(4000)] == pings
    # 4000 samples: the mean within 4 standard errors, the spread within 5 %
    assert abs(statistics.fmean(pings) - truth) < 4 * noise / math.sqrt(4000)
    assert statistics.stdev(pings) == pytest.approx(noise, rel=0.05)


# -- obstacles ---------------------------------------------------------------------------------
def test_commands_place_move_remove_and_refuse_with_a_reason() -> None:
    commands = ObstacleCommands(Obstacles())
    ok, line = commands.take(json.dumps({'place': 'box', 'x': 2, 'y': 0.5, 'size': 0.3}), 1)
    assert ok and 'box placed at (2.000, 0.500)' in line
    ok, _ = commands.take('{"place": "box", "x": 4, "y": 0, "size": 0.3}', 2)
    assert ok and [(o.x, o.y) for o in commands.obstacles] == [(4.0, 0.0)]  # moved
    for text, reason, words in [
            ('{"place": "box", "x": "far", "y": 0, "size": 0.3}', 'bad_command', 'key x'),
            ('{"place": "box", "x": 1, "y": 0, "size": 0}', 'bad_command', 'key size: 0'),
            ('{"place": "box", "x": 1, "y": 0, "size": 0.2, "z": 1}', 'bad_command', 'key z'),
            ('{"remove": "crate"}', 'unknown_obstacle', "'crate' is no obstacle"),
            ('{"place": "a", "remove": "box"}', 'bad_command', 'needs one of'),
            ('box at 1, 2', 'not_json', 'not JSON')]:
        ok, line = commands.take(text, 3)
        assert not ok and words in line and commands.rejects[reason] >= 1, line
    assert len(commands.obstacles) == 1 and commands.rejected == 6 and commands.accepted == 2
    ok, _ = commands.take('{"remove": "box"}', 4)
    assert ok and len(commands.obstacles) == 0


def test_a_layout_places_obstacles_and_refuses_a_bad_one(tmp_path: Path) -> None:
    path = tmp_path / 'boxes_1991.yaml'
    path.write_text(LAYOUT + OBSTACLES)
    lay = load_layout(path)
    assert [(o.name, o.x, o.size) for o in lay.obstacles] == [('pallet', 6.0, 0.4)]
    path.write_text(LAYOUT + OBSTACLES.replace('0.4', '-1'))
    with pytest.raises(LayoutError, match=r'boxes_1991.yaml: key obstacles\[0\].size: -1'):
        load_layout(path)


# -- the stop's rules --------------------------------------------------------------------------
def test_one_near_echo_stops_and_clear_pings_beyond_the_margin_resume() -> None:
    p = ObstacleStopParams()
    stop, clear, pings = (default(ObstacleStopParams, k)
                          for k in ('stop_range', 'clear_margin', 'clear_pings'))
    o = ObstacleStop(p, Notes())
    o.reading(stop + 0.01, 0.0)
    assert not o.holding
    o.reading(stop - 0.01, 0.1)
    assert o.holding and o.stops == 1 and 'Obstacle detected at' in o.notes.texts()[-1]
    for k in range(10):  # beyond the stop range but within the margin: still held
        o.reading(stop + clear_margin_inside(clear), 0.2 + k * 0.1)
    assert o.holding
    for k in range(int(pings) - 1):
        o.reading(stop + clear + 0.01, 1.2 + k * 0.1)
        assert o.holding, k
    o.reading(math.inf, 2.0)
    assert not o.holding and 'the way is clear' in o.notes.texts()[-1]
    for near in (-math.inf, math.nan):  # too near to time, or no number: a stop
        o = ObstacleStop(p, Notes())
        o.reading(near, 0.0)
        assert o.holding


def clear_margin_inside(margin: float) -> float:
    """Return a distance past the stop range but inside the clear margin."""
    return margin / 2.0


def test_switched_off_the_sonar_holds_nothing() -> None:
    p = ObstacleStopParams(enabled=False)
    o = ObstacleStop(p, Notes())
    o.reading(0.1, 0.0)
    o.check(10.0)
    assert not o.holding and o.health() == (0, 'sonar off')


def test_a_silent_sonar_latches_until_the_next_leg_and_an_unheard_one_is_said() -> None:
    silent = default(ObstacleStopParams, 'silent_time')
    o = ObstacleStop(ObstacleStopParams(), Notes())
    o.check(100.0)
    assert not o.silent and o.health() == (1, 'sonar not heard yet')
    o.reading(5.0, 1.0)
    o.check(1.0 + silent)
    assert not o.silent
    o.check(1.0 + silent + 0.001)
    assert o.silent and o.holding and o.health()[0] == 2
    o.reading(5.0, 2.0)  # heard again: still latched
    assert o.silent
    o.clear()
    assert not o.holding


# -- the camera truck in lock step -------------------------------------------------------------
LAYOUT = straight_tape('boxes_1991', 'a straight tape, the truck 1 m along it', 12.0, 1.0)
OBSTACLES = """\
obstacles:
  - {name: pallet, x: 6.0, y: 0.0, size: 0.4}
"""
BOX = Obstacle('box', 4.0, 0.0, 0.3)  # on the tape, 3 m ahead of where the truck starts


def camera_truck(tmp_path: Path) -> Harness:
    path = tmp_path / 'boxes_1991.yaml'
    path.write_text(LAYOUT)
    return truck(str(path), seed=3)


def sonar_gap(h: Harness) -> float:
    """Ground truth: the transducer to the box's near surface (m), the box dead ahead."""
    s = h.world.vehicle.state
    mount = default(SonarParams, 'mount')
    sx, sy = s.x + mount * math.cos(s.heading), s.y + mount * math.sin(s.heading)
    return math.hypot(BOX.x - sx, BOX.y - sy) - BOX.radius


def test_an_obstacle_placed_ahead_stops_the_truck_short_and_removed_lets_it_finish(
        tmp_path: Path) -> None:
    h = camera_truck(tmp_path)
    ex, rf, s = h.cores['executive'], h.cores['route_following'], h.world.vehicle.state
    h.run(0.5)
    x0 = s.x
    submit(h, 'tape for 6.0 m')
    h.run(3.0)
    assert s.speed > 0.3 and sonar_gap(h) > 2.0  # under way, the box not yet placed
    h.world.obstacles.place(BOX)
    assert h.run(20.0, until=lambda: rf.obstacle.blocked)
    v = s.speed  # ground truth when route following took the first near echo
    h.run(3.0)
    assert abs(s.speed) < 1e-3 and rf.status()['state'] == 'obstacle'
    gap = sonar_gap(h)
    # The band the parameters give: the first echo nearer than stop_range is at most one ping
    # period late (and the noise may bring it 3 sigma early or late); then one loop period and
    # a world step to the motor cut, and the coast (the longest: the declared deceleration).
    stop = default(ObstacleStopParams, 'stop_range')
    sigma = default(SonarParams, 'noise')
    late = v / default(SonarParams, 'rate') + v * (default(RouteParams, 'period')
                                                    + 1 / default(WorldParams, 'sample_rate'))
    coast = v * v / (2 * default(Concic2Params, 'coast_deceleration'))
    assert stop - late - coast - 3 * sigma <= gap <= stop + 3 * sigma, (gap, v)
    assert h.world.sonar.p.min_range < gap  # still seen: the hold lasts
    held_at = s.x
    h.run(5.0)  # the truck stays stopped while the box stands, the task still running
    assert abs(s.x - held_at) < 1e-3 and ex.report['state'] == 'running', ex.report
    h.world.obstacles.remove('box')
    assert h.run(40.0, until=lambda: ex.report['state'] in ('completed', 'failed'))
    assert ex.report['state'] == 'completed', ex.report
    # the leg's 6 m by ground truth, within the parking stop's 5 mm (Rajagopalan 1991, 7.3.4)
    assert s.x - x0 == pytest.approx(6.0, abs=0.005 + 0.002)  # + the odometry's mm counts
    lines = ex.notes.texts()
    assert any('Obstacle detected after' in t for t in lines), lines
    assert any('obstacle removed after' in t for t in lines), lines
    assert any(t.startswith('Obstacle detected at') for t in rf.notes.texts())


def test_a_sonar_gone_silent_stops_the_truck_and_fails_the_task_naming_it(
        tmp_path: Path) -> None:
    h = camera_truck(tmp_path)
    ex, s = h.cores['executive'], h.world.vehicle.state
    h.run(0.5)
    submit(h, 'tape for 8.0 m')
    h.run(3.0)
    v = s.speed
    assert v > 0.3
    h.world.p.sonar.enabled = False  # the sonar stops sending
    x0, t0 = s.x, h.now
    assert h.run(10.0, until=lambda: ex.report['state'] == 'failed')
    assert (ex.report['cause'], ex.report.get('detail')) == ('drive_fault', 'sonar_silent'), \
        ex.report
    h.run(2.0)
    assert abs(s.speed) < 1e-3
    # At most silent_time after the last ping (at most t0), one loop period and a world step
    # to the motor cut, then the coast.
    budget = default(ObstacleStopParams, 'silent_time') + default(RouteParams, 'period') \
        + 1 / default(WorldParams, 'sample_rate')
    coast = v * v / (2 * default(Concic2Params, 'coast_deceleration'))
    assert s.x - x0 <= v * budget + coast, (s.x - x0, h.now - t0)


# -- the 1983 truck: no sonar, a bumper --------------------------------------------------------
def test_a_disc_touches_an_outline_by_its_edge_corner_or_from_inside() -> None:
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]  # anticlockwise

    def touch(x: float, y: float, size: float) -> bool:
        return Obstacles([Obstacle('o', x, y, size)]).touching(square) is not None

    assert touch(0.5, 0.5, 0.01)  # inside
    assert touch(1.25, 0.5, 0.5) and not touch(1.25, 0.5, 0.49)  # 0.25 m beyond an edge
    corner = 0.25 * math.sqrt(2.0)  # off a corner along the diagonal
    assert touch(1.25, 1.25, 2 * corner + 1e-9) and not touch(1.25, 1.25, 2 * corner - 1e-6)


def test_the_tug_runs_into_an_obstacle_and_its_bumper_stops_it() -> None:
    from agv_nodes.world.settings import ElectrukParams

    h = truck('demo_1983', seed=2)
    s = h.world.vehicle.state
    x0, heading = s.x, s.heading
    assert heading == 0.0  # the demo floor's start: along +x on a straight
    front = default(ElectrukParams, 'wheelbase') + default(ElectrukParams, 'front_overhang')
    h.world.obstacles.place(Obstacle('crate', x0 + front + 1.5, s.y, 0.3))
    h.run(0.5)
    submit(h, 'stop at 2 first')
    assert h.run(30.0, until=lambda: h.world.bumper)
    # the bumper meets the crate 1.5 - 0.15 m on, within a world sample's travel
    reach = s.x - x0
    assert 1.35 <= reach <= 1.35 + s.speed / default(WorldParams, 'sample_rate') + 1e-6, reach
    assert [e['event'] for e in h.events].count('collision') == 1
    h.run(5.0)
    assert abs(s.speed) < 1e-3
    ex = h.cores['executive'].report
    assert (ex['state'], ex['cause']) == ('failed', 'collision'), ex
