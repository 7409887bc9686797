"""System 13 over DDS: an obstacle placed ahead of the running camera truck, then a silent sonar.

The launched graph of the CONCIC-II (world, route following, executive, communications, each its
own process) drives a straight tape written for the test. An obstacle placed on world/obstacles
while the truck runs stops it short of the obstacle (ground truth: /world/pose and the
obstacle's position, in the band the declared parameters give), route following's /diagnostics
says Obstacle detected and the executive reports it; removed, the truck sets off again and
finishes its leg. A sonar silenced while the truck drives (the world's `sonar.enabled`) stops it
and fails the task, naming the fault (Rajagopalan 1991, 6.3.11; docs/ultrasonic.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from graph_probe import GraphProbe
import pytest
from tape_floors import straight_tape

from agv_nodes.route_following.settings import ObstacleStopParams, RouteParams
from agv_nodes.settings import parameters
from agv_nodes.world.settings import Concic2Params, SonarParams, WorldNodeSettings, WorldParams

pytestmark = [pytest.mark.dds, pytest.mark.slow]

LAYOUT = straight_tape('boxes_1991', 'a straight tape, the truck 1 m along it', 12.0, 1.0)
BOX = {'place': 'box', 'x': 5.0, 'y': 0.0, 'size': 0.3}  # on the tape, 4 m from the start
CRUISE = 0.3  # m/s: under way (camera_speed 0.47)


def default(cls: type, name: str) -> float:
    """Return a parameter's declared default (the parameter files, not the code under test)."""
    return next(p.default for p in parameters(cls) if p.name == name)


def probe(tmp_path: Path) -> GraphProbe:
    path = tmp_path / 'boxes_1991.yaml'
    path.write_text(LAYOUT)
    return GraphProbe(tmp_path / 'logs', layout=str(path))


def late_and_coast(v: float) -> tuple[float, float]:
    """Return (m travelled before the motor cut, after a sensing delay of 0) and the coast (m).

    One loop period of route following, a world step, and the pacing's lag (a node may run up
    to max_lag behind the world) at speed `v`; the coast at the declared deceleration.
    """
    delay = default(RouteParams, 'period') + 1 / default(WorldParams, 'sample_rate') \
        + default(WorldNodeSettings, 'max_lag')
    return v * delay, v * v / (2 * default(Concic2Params, 'coast_deceleration'))


@pytest.mark.timeout(300)
def test_an_obstacle_stops_the_running_truck_short_and_removed_it_finishes(tmp_path) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import String
    from visualization_msgs.msg import Marker, MarkerArray

    from agv_nodes import qos

    g = probe(tmp_path)
    said: list[str] = []
    g.node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: said.extend(s.message for s in m.status if 'route_following' in s.name),
        qos.EVENTS)
    obstacles = g.node.create_publisher(String, 'world/obstacles', qos.EVENTS)
    drawn: list[set[tuple[str, float, float, float]]] = []  # the world's obstacle markers
    g.node.create_subscription(MarkerArray, 'world/obstacle_markers', lambda m: drawn.append(
        {(k.text, k.pose.position.x, k.pose.position.y, k.scale.x) for k in m.markers
         if k.action == Marker.ADD}), qos.LATCHED)
    mount = default(SonarParams, 'mount')
    try:
        g.start_task('tape for 6.0 m', cruise=CRUISE)
        x0 = g.path[0][1]
        placed_at = g.path[-1][1]
        assert BOX['x'] - BOX['size'] / 2 - (placed_at + mount) > 1.5, placed_at
        obstacles.publish(String(data=json.dumps(BOX)))
        since = g.stays_at_rest(hold=3.0, what='the truck to stop for the obstacle')
        _t, x, y = g.path[-1]
        # ground truth: the transducer (mount ahead of the axle, along the straight tape) to
        # the box's near surface
        gap = math.hypot(BOX['x'] - (x + mount), BOX['y'] - y) - BOX['size'] / 2
        v = default(RouteParams, 'camera_speed')  # the cruise it was stopped from
        late, coast = late_and_coast(v)
        stop, sigma = default(ObstacleStopParams, 'stop_range'), default(SonarParams, 'noise')
        ping = v / default(SonarParams, 'rate')  # the first near echo up to a ping late
        assert stop - ping - late - coast - 3 * sigma <= gap <= stop + 3 * sigma, gap
        g.spin_until(lambda: any(m.startswith('Obstacle detected') for m in said), 30,
                     "route following's /diagnostics to say Obstacle detected")
        assert not any('FAILED' in r for r in g.reports), g.reports
        # the viewers' picture of the floor follows: the box drawn where it was placed, then
        # gone (latched, so the first sample is the empty floor)
        assert drawn[0] == set() and (BOX['place'], BOX['x'], BOX['y'], BOX['size']) in \
            set().union(*drawn), drawn
        obstacles.publish(String(data=json.dumps({'remove': 'box'})))
        g.report_with('completed', wall_limit=120)
        assert drawn[-1] == set(), drawn
        end = g.path[-1][1]
        assert g.time > since + 3.0 and end - x0 == pytest.approx(6.0, abs=0.01), (x0, end)
        logs = '\n'.join(p.read_text(errors='replace')
                         for p in (tmp_path / 'logs').rglob('*') if p.is_file())
        for words in ('Obstacle detected after', 'obstacle removed after',
                      'obstacle box placed at (5.000, 0.000)', 'obstacle box removed'):
            assert words in logs, words
    finally:
        g.close()


@pytest.mark.timeout(300)
def test_a_sonar_gone_silent_stops_the_truck_and_fails_the_task(tmp_path, fault_table) -> None:
    g = probe(tmp_path)
    try:
        g.start_task('tape for 8.0 m', cruise=CRUISE)
        silenced = g.at_exact_time(lambda: g.set_world(**{'sonar.enabled': False}))
        g.report_with('FAILED', wall_limit=60)
        assert any('drive fault (route): sonar silent' in r for r in g.reports), g.reports
        rest = g.stays_at_rest() - silenced
        moved = g.travelled_since(silenced)
        v = default(RouteParams, 'camera_speed')
        late, coast = late_and_coast(v)
        assert moved <= v * default(ObstacleStopParams, 'silent_time') + late + coast, moved
        fault_table.add("the camera truck's sonar silenced on a tape leg",
                        'stopped within silent_time 0.5 s + a loop, a step, max_lag and the '
                        'coast; task failed: drive fault sonar silent',
                        f'{moved * 1000:.0f} mm travelled, at rest {rest:.2f} s after, '
                        'FAILED: drive fault (route): sonar silent')
    finally:
        g.close()
