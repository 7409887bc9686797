"""The live view over a running graph: a plain Foxglove client finds and decodes every part.

The graph runs demo_1983 over DDS (test/graph_probe.py) with its live view, as `agv-launch
--foxglove` starts it (port 0: a free one, which live_view names in its output).
A client written from the Foxglove WebSocket protocol alone (test/foxglove_client.py; protobuf
payloads decoded from the schemas the server advertises) connects, finds the scene, the
transforms and the decoded record channels, and decodes a message of each. What it decodes is
held against the layout file (the cards and wires it draws), the record tables (the decoded
fields) and the world's ground truth (the odometry).
"""

from __future__ import annotations

import math
from pathlib import Path
import re
import time

from foxglove_client import FoxgloveClient
from graph_probe import GraphProbe
import pytest

from agv_nodes.package_share import config_dir
from agv_nodes.world.layout import load_layout

pytestmark = [pytest.mark.dds, pytest.mark.slow]

# Wheel odometry against the ground truth, as far as wheel odometry can know it. The world's
# wheels do not slip; the counters are whole millimetres of each wheel's cumulative travel, so
# the heading, from their difference over the 0.8 m track (world electruk.track), is off by up
# to 1 mm / 0.8 m at any time, and the position by that angle times the distance driven, plus
# a counter's own rounding. Measured: 1.1 mm after 21.8 m round the east bend.
ODOM_PER_METRE = 0.001 / 0.8  # m of position error per m driven
ODOM_FLOOR = 0.0005  # m: a counter's rounding


def served_port(log: Path) -> int:
    """Return the port live_view says (in its log) it serves on."""
    deadline = time.monotonic() + 60
    while True:
        text = log.read_text() if log.exists() else ''
        found = re.search(r'ws://127\.0\.0\.1:(\d+)', text)
        if found:
            return int(found.group(1))
        assert time.monotonic() < deadline, f'live_view said no port: {text}'
        time.sleep(0.1)


@pytest.mark.timeout(400)
def test_a_plain_foxglove_client_finds_and_decodes_the_live_run(tmp_path):
    from nav_msgs.msg import Odometry

    from agv_nodes import qos

    g = GraphProbe(tmp_path / 'logs', foxglove=0, bag=tmp_path / 'bag')
    client = None
    try:
        port = served_port(tmp_path / 'logs' / 'live_view.log')
        odom: list[tuple[float, float, float]] = []
        g.node.create_subscription(
            Odometry, 'odom', lambda m: odom.append((
                m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, m.pose.pose.position.x,
                m.pose.pose.position.y)), qos.EVENTS)
        g.start_task('stop at 1')  # round the east bend, 180 degrees
        client = FoxgloveClient(f'ws://127.0.0.1:{port}')
        topics = ['/scene', '/tf', '/decoded/traction/command', '/decoded/hw/wheel_odometry',
                  '/reports']
        client.wait_for_channels(topics, timeout=30)
        client.subscribe(topics)
        got = client.first_of_each(
            topics, timeout=60,
            want=lambda topic, msg: topic != '/tf' or len(msg.get('transforms', [])) >= 3)
        layout = load_layout(config_dir() / 'layouts' / 'demo_1983.yaml')
        ids = {e['id'] for e in got['/scene']['entities']}
        assert {f'marker/{k}' for k in range(len(layout.markers))} <= ids
        assert {f'path/{pid}' for pid in layout.paths} <= ids
        assert 'truck/body' in ids and 'truck/marker_lens' in ids
        frames = {(t['parent_frame_id'], t['child_frame_id'])
                  for t in got['/tf']['transforms']}
        assert {('map', 'odom'), ('odom', 'base_link'), ('base_link', 'marker_lens')} <= frames
        lens = next(t for t in got['/tf']['transforms'] if t['child_frame_id'] == 'marker_lens')
        # the lens: on the front axle (wheelbase 1.2 m), `sensor.lateral` right of it
        assert lens['translation']['x'] == pytest.approx(1.2)
        assert lens['translation']['y'] == pytest.approx(-layout.sensor_lateral)
        command = got['/decoded/traction/command']
        assert command['verdict'] == 'accepted' and -80 <= command['demand'] <= 80
        assert set(command) >= {'manual', 'demand', 'executive_priority', 'e2e_counter', 'raw'}
        wheels = got['/decoded/hw/wheel_odometry']
        assert wheels['verdict'] == 'accepted' and 'left_distance' in wheels
        assert 'e2e_counter' not in wheels  # a hardware record: no E2E
        # The odometry in odom, placed in map where the truck stood, against the ground truth.
        # The odometry in odom, placed in map by the view's map -> odom, against the ground
        # truth once the truck has stopped at W1.1 (a stamp is the view's time of receipt, so
        # only a truck at rest compares without the links' latency).
        g.report_with('completed', wall_limit=300)
        g.stays_at_rest()
        g.spin_until(lambda: bool(odom), 10, 'odometry')
        anchor = next(t for t in got['/tf']['transforms'] if t['child_frame_id'] == 'odom')
        ax, ay = anchor['translation'].get('x', 0.0), anchor['translation'].get('y', 0.0)
        q = anchor['rotation']
        heading = 2.0 * math.atan2(q.get('z', 0.0), q.get('w', 0.0))
        c, s = math.cos(heading), math.sin(heading)
        _t, x, y = odom[-1]
        placed = (ax + c * x - s * y, ay + s * x + c * y)
        driven = sum(math.dist(a[1:], b[1:]) for a, b in zip(g.path, g.path[1:], strict=False))
        error = math.dist(placed, g.path[-1][1:])
        print(f'odometry at rest after {driven:.2f} m: {error * 1000:.1f} mm from the truth')
        turned = [math.atan2(b[2] - a[2], b[1] - a[1])
                  for a, b in zip(g.path, g.path[10:], strict=False)
                  if math.dist(a[1:], b[1:]) > 0.05]
        assert max(turned) - min(turned) > math.radians(150)  # the odometry's heading counts
        assert driven > 5.0 and error <= ODOM_FLOOR + ODOM_PER_METRE * driven, (error, driven)
    finally:
        if client is not None:
            client.close()
        g.close()
    bag_read_back(tmp_path / 'bag')


def bag_read_back(bag: Path) -> None:
    """Read the run's bag back: its decoded records (mcap) and its frames (rosbags)."""
    import json

    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    with (bag / 'decoded.mcap').open('rb') as f:
        verdicts: dict[str, set[str]] = {}
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema.encoding == 'jsonschema' and channel.message_encoding == 'json'
            verdicts.setdefault(channel.topic, set()).add(json.loads(message.data)['verdict'])
    assert verdicts['/decoded/traction/command'] == {'accepted'}
    assert verdicts['/decoded/hw/wheel_odometry'] == {'accepted'}
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        tf = [c for c in reader.connections if c.topic in ('/tf', '/tf_static')]
        assert {c.topic for c in tf} == {'/tf', '/tf_static'}
        children = set()
        for connection, _t, raw in reader.messages(connections=tf):
            msg = typestore.deserialize_cdr(raw, connection.msgtype)
            children |= {t.child_frame_id for t in msg.transforms}
    assert children == {'odom', 'base_link', 'marker_lens'}
