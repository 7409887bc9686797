"""The live view draws the world's obstacles as they stand, over DDS and the Foxglove protocol.

A `live_view` process takes the world's latched `world/obstacle_markers`; a plain Foxglove
protocol client (test/foxglove_client.py) must then find each obstacle in `/scene` where the
test placed it, at its size, and see it deleted once the world no longer has it. The expected
positions and sizes are the test's own numbers; the markers are built as the world builds them
(agv_nodes.world.viz.obstacle_markers) from obstacles the test writes.
"""

from __future__ import annotations

import os
from pathlib import Path
import re
import struct
import subprocess
import sys
import time

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from foxglove_client import MESSAGE_DATA, FoxgloveClient  # noqa: E402

pytestmark = pytest.mark.dds


def _port(proc: subprocess.Popen, deadline: float) -> int:
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        found = re.search(r'ws://127\.0\.0\.1:(\d+)', line)
        if found:
            return int(found.group(1))
        assert proc.poll() is None, 'live_view ended before it served'
    raise AssertionError('live_view said no port')


def _scenes(client: FoxgloveClient, want, timeout: float) -> dict:
    """Return the first /scene message `want` accepts."""
    deadline = time.monotonic() + timeout
    while True:
        frame = client._next(deadline, 'no /scene with the obstacles as placed')
        if frame is None or frame[0] != MESSAGE_DATA:
            continue
        sub_id, _t = struct.unpack_from('<IQ', frame, 1)
        msg = client.decode(client._subs[sub_id], frame[13:])
        if want(msg):
            return msg


@pytest.mark.timeout(120)
def test_obstacles_placed_and_removed_show_in_the_scene():
    import rclpy
    from visualization_msgs.msg import MarkerArray

    from agv_nodes import qos
    from agv_nodes.world.obstacles import Obstacle
    from agv_nodes.world.viz import obstacle_markers

    proc = subprocess.Popen(
        [sys.executable, '-m', 'agv_nodes.view.live', '--ros-args', '-p', 'port:=0',
         '-p', 'layout:=demo_1983', '-p', 'scene_period:=60.0'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('obstacle_world', context=context)
    client = None
    try:
        port = _port(proc, time.monotonic() + 60)
        client = FoxgloveClient(f'ws://127.0.0.1:{port}')
        client.wait_for_channels(['/scene'], timeout=30)
        client.subscribe(['/scene'])
        pub = node.create_publisher(MarkerArray, 'world/obstacle_markers', qos.LATCHED)
        placed = [Obstacle('box', 2.0, -0.5, 0.3), Obstacle('post', -1.25, 3.5, 0.1)]
        pub.publish(obstacle_markers(placed))

        def has_obstacles(msg: dict) -> bool:
            return any(e['id'].startswith('obstacle/') for e in msg.get('entities', []))

        # latched: the sample reaches the view once the two have matched, whenever that is
        scene = _scenes(client, has_obstacles, timeout=60)
        shown = {e['id']: e for e in scene['entities'] if e['id'].startswith('obstacle/')}
        assert set(shown) == {'obstacle/box', 'obstacle/post'}
        for item in placed:
            post = shown[f'obstacle/{item.name}']['cylinders'][0]
            assert post['pose']['position']['x'] == pytest.approx(item.x)
            assert post['pose']['position']['y'] == pytest.approx(item.y)
            assert post['size']['x'] == pytest.approx(item.size)
            assert post['size']['y'] == pytest.approx(item.size)
        pub.publish(obstacle_markers(placed[1:]))  # the box taken away
        scene = _scenes(client, lambda m: bool(m.get('deletions')), timeout=30)
        assert [d['id'] for d in scene['deletions']] == ['obstacle/box']
        ids = {e['id'] for e in scene['entities'] if e['id'].startswith('obstacle/')}
        assert ids == {'obstacle/post'}
    finally:
        if client is not None:
            client.close()
        proc.terminate()
        proc.wait(20)
        node.destroy_node()
        rclpy.shutdown(context=context)
