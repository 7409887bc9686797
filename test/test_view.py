"""The live view's ROS-free parts: dead reckoning, the frames, the scene and decoded records.

Expected values come from geometry (a wheel pair on a circle), the layout files and the record
tables, and a decoded record is validated against its JSON schema by jsonschema.
"""

from __future__ import annotations

import math

import jsonschema
import pytest

from agv_nodes.package_share import config_dir
from agv_nodes.records import codec
from agv_nodes.records.decoded import decoded, decoded_topic, json_schema
from agv_nodes.records.ports import RecordReader, RecordWriter
from agv_nodes.view.frames import TruckShape, sensor_frames
from agv_nodes.view.odometry import WheelDeadReckoning
from agv_nodes.view.scene import floor_entities
from agv_nodes.world.layout import load_layout

TRACK = 0.8


def counters(left: float, right: float, speed: float = 0.0) -> dict[str, int]:
    """wheel_odometry fields for cumulative wheel travel (m), as the mm counters wrap."""
    return {'left_distance': round(left * 1000) & 0xFFFF,
            'right_distance': round(right * 1000) & 0xFFFF,
            'left_speed': round(speed * 1000), 'right_speed': round(speed * 1000)}


@pytest.mark.timeout(30)
@pytest.mark.parametrize('radius', [2.5, -3.0, 1e9])
def test_dead_reckoning_follows_a_circle(radius):
    # The axle centre on a circle of `radius` (left +): after an arc of length s the wheels
    # have run s (1 -+ track / 2R), the pose is (R sin a, R (1 - cos a)), heading a = s / R.
    odo = WheelDeadReckoning(TRACK)
    steps, length = 400, 40.0  # past the 65.5 m wrap of neither counter, 40 m of arc
    for k in range(steps + 1):
        s = length * k / steps
        odo.update(counters(s * (1 - TRACK / 2 / radius), s * (1 + TRACK / 2 / radius)))
    a = length / radius
    p = odo.pose
    assert p.x == pytest.approx(radius * math.sin(a), abs=0.01)
    assert p.y == pytest.approx(radius * (1 - math.cos(a)), abs=0.01)
    assert math.remainder(p.heading - a, 2 * math.pi) == pytest.approx(0.0, abs=0.002)


@pytest.mark.timeout(30)
def test_dead_reckoning_takes_the_counters_wrap():
    odo = WheelDeadReckoning(TRACK)
    for k in range(0, 200):  # 100 m straight: each counter wraps at 65.536 m
        odo.update(counters(k * 0.5, k * 0.5))
    assert odo.pose.x == pytest.approx(99.5, abs=1e-9) and odo.pose.heading == 0.0


@pytest.mark.timeout(30)
def test_the_truck_frames_sit_where_the_layout_puts_its_sensors():
    lay = load_layout(config_dir() / 'layouts' / 'demo_1983.yaml')
    shape = TruckShape('electruk', 1.8, 0.9, 1.2, lay.sensor_lateral, 0.0)
    (lens,) = sensor_frames(shape)
    assert lens == ('marker_lens', 1.2, -0.45, -math.pi / 2)  # right of the front axle
    cams = sensor_frames(TruckShape('concic2', 1.3, 0.5, 0.0, 0.0, 0.64))
    assert cams == [('camera_front', 0.64, 0.0, 0.0), ('camera_rear', -0.64, 0.0, math.pi)]


@pytest.mark.timeout(30)
@pytest.mark.parametrize('name', ['demo_1983', 'signs_1991'])
def test_the_floor_scene_draws_every_path_and_card(name):
    lay = load_layout(config_dir() / 'layouts' / f'{name}.yaml')
    entities = floor_entities(lay)
    assert len(entities) == len(lay.paths) + len(lay.markers) + len(
        {m.station for m in lay.markers if m.station})


@pytest.mark.timeout(30)
def test_decoded_records_carry_fields_and_verdict_and_match_their_schema():
    schema = codec()['traction_command']
    writer, reader = RecordWriter(schema, 'e2e'), RecordReader(schema, 'e2e')
    raw = writer.pack({'demand': 25})
    message = decoded(reader, raw, 0)
    jsonschema.validate(message, json_schema(schema))
    assert message['verdict'] == 'accepted' and message['demand'] == 25
    assert message['e2e_counter'] == raw[14] and message['raw'] == raw.hex()
    again = decoded(reader, raw, 1)  # the same counter: not new data
    assert again['verdict'] == 'repeated_counter' and again['demand'] == 25
    bad = bytearray(writer.pack({'demand': 25}))
    bad[1] ^= 0x40
    broken = decoded(reader, bytes(bad), 2)
    assert broken['verdict'] == 'bad_crc' and 'demand' not in broken
    jsonschema.validate(broken, json_schema(schema))
    assert decoded_topic(schema) == '/decoded/traction/command'
    assert decoded_topic(schema, 'agv2') == '/agv2/decoded/traction/command'


@pytest.mark.timeout(30)
def test_every_records_schema_is_a_valid_json_schema():
    for schema in codec():
        jsonschema.Draft202012Validator.check_schema(json_schema(schema))


@pytest.mark.timeout(30)
def test_the_foxglove_layout_plots_fields_the_live_view_serves():
    """config/foxglove/agv_layout.json names only what live_view serves.

    Every topic is one of its channels, every plotted field one of its record's table.
    """
    import json

    layout = json.loads((config_dir() / 'foxglove' / 'agv_layout.json').read_text())
    by_topic = {decoded_topic(s): s for s in codec()}
    channels = {*by_topic, '/scene', '/tf', '/reports', '/hw/camera/front', '/hw/camera/rear'}
    paths = [p['value'] for c in layout['configById'].values() for p in c.get('paths', [])]
    topics = [c['topicPath'] for c in layout['configById'].values() if 'topicPath' in c]
    topics += [c['imageMode']['imageTopic'] for c in layout['configById'].values()
               if 'imageMode' in c]
    topics += list(layout['configById']['3D!floor']['topics'])
    assert paths and topics
    for path in paths:
        topic, _, name = path.partition('.')
        assert topic in by_topic and name in {f.name for f in by_topic[topic].fields}, path
    assert set(topics) <= channels
    panels = set(layout['configById'])

    def leaves(node):
        return {node} if isinstance(node, str) else leaves(node['first']) | leaves(node['second'])

    assert leaves(layout['layout']) == panels


@pytest.mark.timeout(60)
def test_a_bags_decoded_records_and_frames_read_back_with_the_mcap_and_rosbags_libraries(
        tmp_path):
    import json

    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    from agv_nodes.records.carrier import uint8_array_cdr
    from agv_nodes.view.bag_views import BagViews

    ts = get_typestore(Stores.ROS2_JAZZY)
    shape = TruckShape('electruk', 1.8, 0.9, 1.2, 0.45, 0.0)
    views = BagViews(tmp_path, shape, TRACK)
    pose = ts.types['geometry_msgs/msg/PoseStamped']
    header = ts.types['std_msgs/msg/Header']
    stamp = ts.types['builtin_interfaces/msg/Time'](sec=0, nanosec=0)
    point = ts.types['geometry_msgs/msg/Point'](x=2.0, y=1.0, z=0.0)
    square = ts.types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)
    start = pose(header=header(stamp=stamp, frame_id='map'),
                 pose=ts.types['geometry_msgs/msg/Pose'](position=point, orientation=square))
    added = views.take('/agv1/world/pose', bytes(ts.serialize_cdr(start, pose.__msgtype__)), 0)
    (static_topic, static_type, static_raw), = added
    assert static_topic == '/tf_static' and static_type == 'tf2_msgs/msg/TFMessage'
    (lens,) = ts.deserialize_cdr(static_raw, static_type).transforms
    assert (lens.header.frame_id, lens.child_frame_id) == ('agv1/base_link', 'agv1/marker_lens')
    command = codec()['traction_command']
    writer = RecordWriter(command, 'e2e')
    wheels = RecordWriter(codec()['wheel_odometry'], 'none')
    tf = []
    for k in range(1, 11):  # one metre straight, 10 cm a record
        views.take('/agv1/traction/command', uint8_array_cdr(writer.pack({'demand': 30})), k)
        tf += views.take('/agv1/hw/wheel_odometry', uint8_array_cdr(wheels.pack(
            counters(0.1 * k, 0.1 * k, 0.5))), k)
    views.close()
    last = ts.deserialize_cdr(tf[-1][2], tf[-1][1]).transforms
    odom = {(t.header.frame_id, t.child_frame_id): t.transform.translation for t in last}
    assert odom[('map', 'agv1/odom')].x == 2.0 and odom[('map', 'agv1/odom')].y == 1.0
    assert odom[('agv1/odom', 'agv1/base_link')].x == pytest.approx(0.9)  # from the 1st record
    with (tmp_path / 'decoded.mcap').open('rb') as f:
        seen = {}
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema.encoding == 'jsonschema' and channel.message_encoding == 'json'
            seen.setdefault(channel.topic, []).append(json.loads(message.data))
    assert set(seen) == {'/agv1/decoded/traction/command', '/agv1/decoded/hw/wheel_odometry'}
    commands = seen['/agv1/decoded/traction/command']
    assert len(commands) == 10 and {c['demand'] for c in commands} == {30}
    assert all(c['verdict'] == 'accepted' for c in commands)
    assert seen['/agv1/decoded/hw/wheel_odometry'][-1]['left_distance'] == 1000
