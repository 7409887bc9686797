"""agv-report --layout: the camera-truck report, from a small bag written here with known contents.

Two legs on junction_1991: forward 2 m along the main tape through a road sign, a left turn and
a wait, ending in no_track (the task FAILED); then 0.8 m in reverse to an idle leg end (the task
completed). The numbers the report gives are checked against what the bag holds.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from agv_nodes.camera_report import STEERED, make_camera_report
from agv_nodes.records import codec
from agv_nodes.records.carrier import uint8_array_cdr
from agv_nodes.report import main

FAILED = "task 1 'tape junctions 1 left': FAILED: lost track (route)"
COMPLETED = "task 2 'tape for 0.8 m': completed"


def _ns(t: float) -> int:
    return round(t * 1e9)


def _status_rows() -> list[tuple[float, dict]]:
    """route_status every 0.1 s: each phase with its own lateral errors (mm)."""
    rows: list[tuple[float, dict]] = []

    def add(t: float, state: str, error: int, leg: int, **extra: int) -> None:
        rows.append((round(t, 1), {'state': state, 'lateral_error': error, 'leg': leg} | extra))

    follow = [3, -4, 5, -2, 0, 1, -6, 2, 4, -3, 2, -1, 0, 3, -2, 1, -1, 2, 0, -5]
    for k, e in enumerate(follow):  # 1.0 .. 2.9 s
        add(1.0 + k / 10, 'following', e, 1, distance=round(k * 5))
    add(3.0, 'sign', 10, 1, distance=100)
    add(3.1, 'sign', -8, 1, distance=105, sign_left=1)
    # the width back to normal: the straight flag and the junction count come after the sign
    add(3.2, 'following', 1, 1, distance=110, sign_left=1, sign_straight=1, junctions=1)
    for k in range(4):  # a turn and a wait: their errors must not count
        add(3.3 + k / 10, 'turning', 50, 1, distance=115, sign_left=1, sign_straight=1,
            junctions=1)
    for k in range(3):
        add(3.7 + k / 10, 'waiting', -60, 1, distance=120, sign_left=1, sign_straight=1,
            junctions=1)
    for k, e in enumerate([2, -2, 3, -1, 0, 1, -4, 2, 1]):  # 4.0 .. 4.8 s
        add(4.0 + k / 10, 'following', e, 1, distance=125 + k * 8, junctions=1)
    add(4.9, 'no_track', 90, 1, distance=200, junctions=1)
    add(5.0, 'idle', 0, 1, distance=200, junctions=1)
    for k, e in enumerate([-3, 4, -2, 5, -1, 0, 2, -2, 3, -4, 1, 0, -1, 2, -3, 1, 0, 2, -1, 1]):
        add(6.0 + k / 10, 'following', e, 2, distance=4 * k)  # 6.0 .. 7.9 s, reverse
    add(8.0, 'idle', 0, 2, distance=80)
    return rows


def _command_rows() -> list[tuple[float, dict]]:
    rows = []
    for k in range(90):  # 0.0 .. 8.9 s
        t = round(k / 10, 1)
        leg = 1 if t < 5.5 else 2
        active = 1.0 <= t < 5.0 or 6.0 <= t < 8.0
        rows.append((t, {'mode': 'camera' if active else 'idle', 'leg': leg if t >= 1.0 else 0,
                         'direction': 'reverse' if leg == 2 else 'forward',
                         'junction': 'left', 'junction_number': 1}))
    return rows


def _poses() -> list[tuple[float, float]]:
    """(t, x) on the main tape, heading along it: 0.5 m/s forward, rest, 0.4 m/s back."""
    poses = [(round(k / 10, 1), 0.0) for k in range(10)]  # 0.0 .. 0.9 s at rest
    poses += [(round(1.0 + k / 10, 1), 0.05 * k) for k in range(41)]  # to 2.0 m at 5.0 s
    poses += [(round(5.1 + k / 10, 1), 2.0) for k in range(10)]  # at rest to 6.0 s
    poses += [(round(6.1 + k / 10, 1), 2.0 - 0.04 * (k + 1)) for k in range(20)]  # 1.2 m at 8 s
    poses += [(round(8.1 + k / 10, 1), 1.2) for k in range(9)]
    return poses


def write_bag(path: Path, commands: bool = True, world_events: bool = True) -> None:
    """Write the run as the recorder would: records as UInt8MultiArray, pose, report strings."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    c = codec()
    T = store.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        def connect(topic: str, msgtype: str):
            return writer.add_connection(topic, msgtype, typestore=store)

        def records(topic: str, name: str, rows: list[tuple[float, dict]]) -> None:
            conn = connect(topic, 'std_msgs/msg/UInt8MultiArray')
            for k, (t, values) in enumerate(rows):
                raw = c[name].encode(values, counter=k % 256) if c[name].protected \
                    else c[name].encode(values, integrity='none')
                writer.write(conn, _ns(t), uint8_array_cdr(raw))

        records('/route/status', 'route_status', _status_rows())
        if commands:
            records('/route/command', 'route_command', _command_rows())
        if world_events:
            records('/world/events', 'world_event', [
                (5.1, {'event': 'stopped', 'speed': 500}),
                (8.1, {'event': 'stopped', 'speed': 400})])
        conn = connect('/world/pose', 'geometry_msgs/msg/PoseStamped')
        for t, x in _poses():
            stamp = T['builtin_interfaces/msg/Time'](sec=int(t), nanosec=_ns(t) % 10**9)
            msg = T['geometry_msgs/msg/PoseStamped'](
                header=T['std_msgs/msg/Header'](stamp=stamp, frame_id='map'),
                pose=T['geometry_msgs/msg/Pose'](
                    position=T['geometry_msgs/msg/Point'](x=x, y=0.0, z=0.0),
                    orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)))
            writer.write(conn, _ns(t), store.serialize_cdr(msg, 'geometry_msgs/msg/PoseStamped'))
        conn = connect('/comms/report', 'std_msgs/msg/String')
        for t, text in ((1.0, "task 1 'tape junctions 1 left': running (step 0)"),
                        (5.0, FAILED), (8.0, COMPLETED)):
            writer.write(conn, _ns(t), store.serialize_cdr(T['std_msgs/msg/String'](data=text),
                                                           'std_msgs/msg/String'))


def _s(t: float):
    """Match a time read back: the bag holds ns, the report s (float rounding)."""
    return pytest.approx(t, abs=1e-9)


def _rms(values: list[int]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values))


def _steered(leg: int) -> list[int]:
    return [f['lateral_error'] for _t, f in _status_rows()
            if f['leg'] == leg and f['state'] in STEERED]


def _check_legs(legs: list[dict]) -> None:
    assert [(g['leg'], g['start'], g['end']) for g in legs] == \
        [(1, _s(1.0), _s(5.0)), (2, _s(6.0), _s(8.0))]
    one, two = legs
    assert one['duration_s'] == pytest.approx(4.0) and two['duration_s'] == pytest.approx(2.0)
    assert one['distance_m'] == pytest.approx(2.0) and two['distance_m'] == pytest.approx(0.8)
    assert one['odometry_distance_m'] == 2.0 and two['odometry_distance_m'] == 0.8
    assert one['junctions'] == 1 and two['junctions'] == 0
    assert one['peak_speed_m_s'] == pytest.approx(0.5)
    assert two['peak_speed_m_s'] == pytest.approx(0.4)
    # the sign's errors count (the tape steers), the turn's 50, the wait's -60 and no_track's 90
    # do not
    errors = _steered(1)
    assert len(errors) == one['lateral_samples'] == 20 + 2 + 1 + 9
    assert one['lateral_rms_mm'] == pytest.approx(_rms(errors), abs=1e-12)
    assert one['lateral_max_mm'] == 10
    assert two['lateral_rms_mm'] == pytest.approx(_rms(_steered(2)), abs=1e-12)
    assert two['lateral_max_mm'] == 5


@pytest.mark.timeout(120)
def test_camera_report_numbers_and_events(tmp_path: Path) -> None:
    """Legs, lateral error, signs, junction phases, stops and tasks as the bag holds them."""
    bag = tmp_path / 'bag'
    write_bag(bag)
    result = make_camera_report(bag, tmp_path / 'out', 'junction_1991')
    _check_legs(result['legs'])
    assert [g['direction'] for g in result['legs']] == ['forward', 'reverse']
    assert result['lateral_rms_mm'] == pytest.approx(_rms(_steered(1) + _steered(2)))

    sign, = result['signs']
    assert (sign['time'], sign['junctions'], sign['leg']) == (_s(3.0), 1, 1)
    assert (sign['left'], sign['right'], sign['straight']) == (1, 0, 1)
    assert sign['where']['tape'] == 'main' and sign['where']['s'] == pytest.approx(1.0)
    turn, wait = result['junction_phases']
    assert (turn['kind'], turn['time'], turn['decision'], turn['junctions']) == \
        ('turning', _s(3.3), 'left', 1)
    assert turn['duration_s'] == pytest.approx(0.4)
    assert (wait['kind'], wait['time']) == ('waiting', _s(3.7))
    assert wait['duration_s'] == pytest.approx(0.3)

    end, leg_end = result['stops']
    assert (end['time'], end['leg'], end['cause'], end['failure']) == \
        (_s(5.1), 1, 'no_track', FAILED)
    assert end['where']['x'] == 2.0 and end['where']['tape'] == 'main'
    assert (leg_end['time'], leg_end['leg'], leg_end['cause'], leg_end['failure']) == \
        (_s(8.1), 2, 'idle (leg end)', None)
    assert leg_end['where']['x'] == 1.2
    assert result['tasks'] == [{'time': _s(5.0), 'text': FAILED},
                               {'time': _s(8.0), 'text': COMPLETED}]

    out = tmp_path / 'out'
    assert json.loads((out / 'report.json').read_text()) == json.loads(json.dumps(result))
    assert result['plots'] == ['camera_path.png', 'camera_timeline.png']
    assert all((out / p).stat().st_size > 10_000 for p in result['plots'])
    summary = (out / 'summary.md').read_text()
    assert '| 1 | forward | 1.0 | 4.0 | 2.00 | 2.00 | 1 |' in summary
    assert '| 3.0 | sign | 1 | flags left straight | main 1.00 m |' in summary
    assert f'| 5.1 | stop |  | no_track; {FAILED} | main 2.00 m |' in summary


@pytest.mark.timeout(120)
def test_camera_report_without_commands_or_world_events(tmp_path: Path, capsys) -> None:
    """From agv-report --layout: legs from route_status's echo, stops from the pose at rest."""
    bag = tmp_path / 'bag'
    write_bag(bag, commands=False, world_events=False)
    assert main([str(bag), '--layout', 'junction_1991', '--out', str(tmp_path / 'out')]) == 0
    assert '2 legs, 2 stops' in capsys.readouterr().out
    result = json.loads((tmp_path / 'out' / 'report.json').read_text())
    _check_legs(result['legs'])
    # at rest once the pose's speed window (0.5 s) holds only the resting poses
    end, leg_end = result['stops']
    assert 5.0 < end['time'] <= 5.3 and end['cause'] == 'no_track'
    assert 8.0 < leg_end['time'] <= 8.3 and leg_end['cause'] == 'idle (leg end)'


# -- the identified track (camera_law feed_forward) against the tape ---------------------------

TRACK_LAYOUT = 'tape_1991'  # the circle of R = 2.95 m; its first road sign is 4 m along
START_S = 0.2  # m along the circle where route following starts: odom's origin


def _tape_1991():
    from agv_nodes.world.layout import layout_path, load_layout

    return load_layout(layout_path(TRACK_LAYOUT))


def _odom_windows(start: tuple[float, float, float], lateral: float = 0.0
                  ) -> list[list[tuple[float, float]]]:
    """Windows of the circle tape 1.5 m long, 0.5 m apart, `lateral` m left of it, in odom.

    odom: the frame whose origin and x axis are the pose `start` (x, y, heading) in the world.
    """
    tape = _tape_1991().paths['circle']
    x0, y0, h0 = start
    c, s = math.cos(h0), math.sin(h0)
    windows = []
    for k in range(4):  # 0.5 .. 3.0 m along: clear of the first sign's branches
        points = []
        for j in range(76):
            x, y, h = tape.pose_at(START_S + 0.3 + 0.5 * k + 0.02 * j)
            x, y = x - lateral * math.sin(h) - x0, y + lateral * math.cos(h) - y0
            points.append((c * x + s * y, -s * x + c * y))
        windows.append(points)
    return windows


def _track_data(windows: list, topic: str = '/route/identified_track') -> dict:
    """Return a data dict as read_bag gives it: the start pose first, the windows at 2 Hz."""
    from collections import defaultdict

    start = _tape_1991().paths['circle'].pose_at(START_S)
    return {'records': defaultdict(list), 'strings': defaultdict(list), 'start': 0.0,
            'end': 3.0, 'pose': [(0.0, *start), (3.0, *start)],
            'paths': {topic: [(1.0 + k / 2, w) for k, w in enumerate(windows)]}}


@pytest.mark.timeout(60)
@pytest.mark.parametrize('topic', ['/route/identified_track', '/truck1/route/identified_track'])
def test_identified_track_is_placed_on_the_tape_by_the_start_pose(topic: str) -> None:
    from agv_nodes.camera_report import analyse_camera, summary_markdown
    from agv_nodes.track_report import identified_track_messages, tape_distance

    layout = _tape_1991()
    start = layout.paths['circle'].pose_at(START_S)
    assert abs(start[2]) > 0.05  # odom is turned against the world: the rotation counts
    on = analyse_camera(_track_data(_odom_windows(start), topic), layout)['identified_track']
    assert on['messages'] == 4 and on['points'] == 4 * 76
    # the tape's polyline (0.02 m chords of R = 2.95 m) lies 0.02 mm inside the arc at most
    assert on['mean_mm'] < 1.0 and on['max_mm'] < 0.05
    # 20 mm left of the tape (towards the centre): 20 mm from it
    shifted = _track_data(_odom_windows(start, lateral=0.02), topic)
    off = analyse_camera(shifted, layout)['identified_track']
    assert off['mean_mm'] == pytest.approx(20.0, abs=0.05)
    assert off['max_mm'] == pytest.approx(20.0, abs=0.05)
    # beside a tape the distance is project()'s |lateral|
    points = np.concatenate([p for _t, p in identified_track_messages(shifted)])
    lateral = [layout.paths['circle'].project(x, y)[1] for x, y in points[::25]]
    assert tape_distance(layout, points[::25]) == pytest.approx(np.abs(lateral), abs=1e-9)
    summary = summary_markdown(analyse_camera(shifted, layout), [])
    assert '- identified track (route/identified_track): 4 messages, 304 points, from the ' \
        'nearest tape centreline mean 20.0 mm, max 20.0 mm.' in summary
    # placed at a start pose 10 mm left of the true one: every point 10 mm that way (up to
    # 10 mm from the tape, less where the circle has turned away from that direction)
    wrong = _track_data(_odom_windows(start), topic)
    t, x, y, h = wrong['pose'][0]
    wrong['pose'][0] = (t, x - 0.01 * math.sin(h), y + 0.01 * math.cos(h), h)
    moved = analyse_camera(wrong, layout)['identified_track']
    assert 5.0 < moved['mean_mm'] < 10.0 and moved['max_mm'] == pytest.approx(10.0, abs=0.1)


@pytest.mark.timeout(60)
def test_without_the_identified_track_nothing_changes() -> None:
    from agv_nodes.camera_report import analyse_camera, summary_markdown

    layout = _tape_1991()
    data = _track_data(_odom_windows(layout.paths['circle'].pose_at(START_S)))
    with_track = analyse_camera(data, layout)
    for paths in ({}, {'/elsewhere/path': data['paths']['/route/identified_track']}, None):
        if paths is None:
            del data['paths']  # a hand-made data dict of before
        else:
            data['paths'] = paths
        result = analyse_camera(data, layout)
        assert 'identified_track' not in result
        assert result == {k: v for k, v in with_track.items() if k != 'identified_track'}
        assert 'identified track' not in summary_markdown(result, [])


def write_track_bag(path: Path) -> tuple[float, float, float]:
    """Write a feed_forward run's pictures as the recorder does; return the start pose.

    The node's own messages (route_following.node's track_path and circle_marker), serialized
    by rclpy as the recorder receives them. An identified track arrives before the world's
    route; the route is published twice (a late-joining recorder gets the latched one again).
    """
    from builtin_interfaces.msg import Time
    from rclpy.serialization import serialize_message
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from agv_nodes.route_following.node import circle_marker, track_path
    from agv_nodes.track_geometry.osculating import Circle
    from agv_nodes.world.viz import layout_messages, pose_message

    layout = _tape_1991()
    start = layout.paths['circle'].pose_at(START_S)
    store = get_typestore(Stores.ROS2_JAZZY)
    route, _cards = layout_messages(layout)
    other, _ = layout_messages(_junction_1991())
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        def write(topic: str, msgtype: str, t: float, msg) -> None:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], _ns(t), serialize_message(msg))

        conns: dict = {}
        for k in range(31):
            t = k / 10
            write('/world/pose', 'geometry_msgs/msg/PoseStamped', t,
                  pose_message(*start, Time(sec=int(t), nanosec=_ns(t) % 10**9)))
        for k, window in enumerate(_odom_windows(start)):
            t = 0.5 + k / 2
            stamp = Time(sec=int(t), nanosec=_ns(t) % 10**9)
            write('/route/identified_track', 'nav_msgs/msg/Path', t, track_path(window, stamp))
            circle = Circle(0.1 * k, -2.95, 2.95, 1 / 2.95) if k % 2 == 0 else \
                Circle(math.nan, math.nan, math.inf, 0.0)  # a straight: DELETE
            write('/route/osculating_circle', 'visualization_msgs/msg/Marker', t,
                  circle_marker(circle, stamp))
            if k < 2:
                write('/world/route', 'nav_msgs/msg/Path', 0.7 + k, route if k == 0 else other)
    return start


def _junction_1991():
    from agv_nodes.world.layout import layout_path, load_layout

    return load_layout(layout_path('junction_1991'))


@pytest.mark.timeout(60)
def test_read_bag_keys_paths_and_circles_by_topic(tmp_path: Path) -> None:
    from agv_nodes.report import read_bag
    from agv_nodes.world.viz import layout_messages

    bag = tmp_path / 'bag'
    start = write_track_bag(bag)
    data = read_bag(bag)
    # the route: the first message of world/route (tape_1991's, not junction_1991's after it)
    route, _cards = layout_messages(_tape_1991())
    assert data['route'] == [(p.pose.position.x, p.pose.position.y) for p in route.poses]
    assert set(data['paths']) == {'/route/identified_track'}
    windows = _odom_windows(start)
    track = data['paths']['/route/identified_track']
    assert [t for t, _p in track] == [_s(0.5), _s(1.0), _s(1.5), _s(2.0)]
    for (_t, points), window in zip(track, windows, strict=True):
        assert np.array(points) == pytest.approx(np.array(window), abs=1e-12)
    assert set(data['markers']) == {'/route/osculating_circle'}
    circles = data['markers']['/route/osculating_circle']
    assert [c[0] for c in circles] == [_s(0.5), _s(1.5)]  # the DELETEs add nothing
    for (_t, *circle), h in zip(circles, (0.0, 0.2), strict=True):
        assert circle == pytest.approx([h, -2.95, 2.95], abs=1e-9)
    assert data['pose'][0] == (_s(0.0), *(pytest.approx(v, abs=1e-12) for v in start))


@pytest.mark.timeout(120)
def test_camera_report_draws_and_measures_the_identified_track(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_track_bag(bag)
    result = make_camera_report(bag, tmp_path / 'out', TRACK_LAYOUT)
    track = result['identified_track']
    assert track['messages'] == 4 and track['points'] == 4 * 76
    assert track['mean_mm'] < 1.0 and track['max_mm'] < 0.05
    out = tmp_path / 'out'
    assert json.loads((out / 'report.json').read_text())['identified_track'] == track
    assert '- identified track (route/identified_track): 4 messages' in \
        (out / 'summary.md').read_text()
    assert (out / 'camera_path.png').stat().st_size > 10_000


@pytest.mark.timeout(60)
@pytest.mark.parametrize('name', ['signs_1991', 'tape_1991'])
def test_tape_distance_is_the_nearest_point_of_any_tape(name: str) -> None:
    """Against every segment of every tape, at random and near the tapes (closed ones' seam)."""
    from agv_nodes.track_report import tape_distance
    from agv_nodes.world.layout import layout_path, load_layout

    layout = load_layout(layout_path(name))
    tapes = [p for pid, p in layout.paths.items() if 'patch' not in pid]
    rng = np.random.default_rng(3)
    on = np.concatenate([p.points for p in tapes])
    points = np.concatenate([rng.uniform(-4.0, 5.0, (300, 2)),
                             on[rng.integers(0, len(on), 300)] + rng.normal(0, 0.03, (300, 2)),
                             [p.points[0] + (0.004, -0.06) for p in tapes]])
    truth = np.full(len(points), np.inf)
    for tape in tapes:
        a, d = tape.points[:-1], np.diff(tape.points, axis=0)
        rel = points[:, None, :] - a[None]
        t = np.clip(np.einsum('pij,ij->pi', rel, d) / np.einsum('ij,ij->i', d, d), 0.0, 1.0)
        truth = np.minimum(truth, np.linalg.norm(rel - t[..., None] * d, axis=2).min(axis=1))
    assert tape_distance(layout, points) == pytest.approx(truth, abs=1e-12)
    # beyond a tape's end the distance to the end, not project()'s lateral (0 in line with it)
    end = _junction_1991()
    assert tape_distance(end, np.array([[6.1, 0.0]])) == pytest.approx([0.1])
    assert end.paths['main'].project(6.1, 0.0)[1] == 0.0
