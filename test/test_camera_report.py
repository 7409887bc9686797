"""agv-report --layout: the camera-truck report, from a small bag written here with known contents.

Two legs on junction_1991: forward 2 m along the main tape through a road sign, a left turn and
a wait, ending in no_track (the task FAILED); then 0.8 m in reverse to an idle leg end (the task
completed). The numbers the report gives are checked against what the bag holds.
"""

import json
import math
from pathlib import Path

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
