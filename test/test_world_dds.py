"""Real DDS: the world node in its own process, driven by a test publisher in another."""

from __future__ import annotations

import json
from pathlib import Path
import subprocess

import pytest

from conftest import PYTHON, REPO

pytestmark = pytest.mark.dds
WORLD = str(Path(PYTHON).parent / 'world')


def test_world_node_publishes_adc_at_340_hz_of_sim_time():
    seconds = 4.0
    world = subprocess.Popen(
        [WORLD, '--ros-args', '-p', 'layout:=straight_track', '-p', 'time_factor:=2.0',
         '-p', f'duration:={seconds + 1.0}',
         '-p', "wait_for_links:=['world>adc_snapshot:1', 'world:traction_drive']",
         # the probe stands in for traction, the writer the world takes traction_drive from
         '-p', "record_writers:=['traction_drive=world_probe']"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    probe = subprocess.run([PYTHON, str(REPO / 'test' / 'world_probe.py'), str(seconds), '60'],
                           capture_output=True, text=True, timeout=120)
    out, _ = world.communicate(timeout=60)
    assert probe.returncode == 0, probe.stderr
    assert world.returncode == 0, out
    state = json.loads(probe.stdout.strip().splitlines()[-1])
    elapsed = state['clock']
    assert elapsed >= seconds
    rate = state['adc'] / elapsed
    assert rate == pytest.approx(340.0, rel=0.01), state
    assert state['speed'] > 300  # the test publisher's drive record moved the truck (mm/s)


def test_world_pause_step_resume_services():
    """~/pause freezes /clock, ~/step advances one sample, ~/resume lets time run again."""
    import rclpy
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import Trigger

    world = subprocess.Popen([WORLD, '--ros-args', '-p', 'layout:=straight_track',
                              '-p', 'time_factor:=1.0', '-p', 'duration:=60.0'],
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    rclpy.init()
    node = rclpy.create_node('world_service_probe')
    clock = {'t': 0.0}
    node.create_subscription(Clock, '/clock', lambda m: clock.__setitem__(
        't', m.clock.sec + m.clock.nanosec * 1e-9), 10)
    clients = {name: node.create_client(Trigger, f'/world/{name}')
               for name in ('pause', 'step', 'resume')}

    def call(name: str) -> Trigger.Response:
        future = clients[name].call_async(Trigger.Request())
        rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
        return future.result()

    def spin(seconds: float) -> None:
        end = __import__('time').monotonic() + seconds
        while __import__('time').monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.02)

    try:
        for client in clients.values():
            assert client.wait_for_service(timeout_sec=30.0)
        spin(0.5)
        assert clock['t'] > 0.0
        assert call('pause').success
        spin(0.3)
        frozen = clock['t']
        spin(0.5)
        assert clock['t'] == frozen  # paused: time stands still
        assert call('step').success
        spin(0.3)
        assert clock['t'] == pytest.approx(frozen + 1 / 340, abs=1e-6)  # exactly one sample
        assert call('resume').success
        spin(0.5)
        assert clock['t'] > frozen + 0.2
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        world.terminate()
        world.wait(timeout=20)


def test_world_waits_for_every_link_it_is_told_of():
    """wait_for_links: no move (and a message naming the link) until every end has matched.

    The reader's node says on graph/links that it has matched its writer, the writer's node
    that its writer has matched all its readers, and the world's own writer has matched its
    readers.
    """
    import rclpy
    from std_msgs.msg import String, UInt8MultiArray

    from agv_nodes import qos
    from agv_nodes.ros_ports import LINKS_TOPIC

    args = [WORLD, '--ros-args', '-p', 'layout:=straight_track', '-p', 'time_factor:=0.0',
            '-p', 'duration:=0.5',
            '-p', "wait_for_links:=['navigation:position_sensor_status', "
                  "'navigation>navigation_status:2', 'world>wheel_odometry:1']"]
    alone = subprocess.run([*args, '-p', 'peer_timeout:=3.0'], capture_output=True, text=True,
                           timeout=60)
    assert alone.returncode == 1, alone.stdout + alone.stderr
    assert ("links still missing: ['navigation:position_sensor_status', "
            "'navigation>navigation_status:2 (has 0)', 'world>wheel_odometry:1 (has 0)']"
            in alone.stderr)
    assert 'moving' not in alone.stdout + alone.stderr

    rclpy.init()
    node = rclpy.create_node('navigation')  # stands in for the node that reads the record
    try:
        pub = node.create_publisher(String, LINKS_TOPIC, qos.LATCHED)
        # its reader has matched, but its writer only one of two readers; nobody reads the
        # world's wheel odometry yet
        pub.publish(String(data='navigation position_sensor_status wheel_odometry '
                                'navigation_status>1'))
        # 10 s: time for the world to discover this node and take its latched word on a
        # loaded machine; two links are still missing when it gives up
        half = subprocess.run([*args, '-p', 'peer_timeout:=10.0'], capture_output=True,
                              text=True, timeout=60)
        pub.publish(String(data='navigation position_sensor_status wheel_odometry '
                                'navigation_status>2'))
        node.create_subscription(UInt8MultiArray, 'hw/wheel_odometry', lambda _m: None,
                                 qos.STREAM_READER)
        told = subprocess.run([*args, '-p', 'peer_timeout:=30.0'], capture_output=True,
                              text=True, timeout=60)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    assert half.returncode == 1, half.stdout + half.stderr
    assert ("links still missing: ['navigation>navigation_status:2 (has 1)', "
            "'world>wheel_odometry:1 (has 0)']" in half.stderr)
    assert told.returncode == 0, told.stdout + told.stderr
    assert 'moving at time_factor 0 (3 links matched at both ends' in told.stdout + told.stderr
