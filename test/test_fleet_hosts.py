"""A truck on another host: its graph in a network namespace of its own, the master on this one.

DDS stays inside the truck (its launcher keeps discovery on its own host's loopback); the master
reaches it only over MQTT, through a virtual Ethernet link, as a central computer reaches a
truck over the radio. Needs the right to make network namespaces (root or CAP_NET_ADMIN); where
the machine does not give it, the test is reported as skipped.
"""

from __future__ import annotations

from collections.abc import Iterator
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

from conftest import PYTHON

BIN = Path(PYTHON).parent
SUBNET = '10.231.{}.{}'


def ip(*args: str) -> subprocess.CompletedProcess:
    """Run `ip ARGS`; the result (the caller checks it)."""
    return subprocess.run(['ip', *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def truck_host() -> Iterator[tuple[str, str, str]]:
    """Yield a network namespace linked to this one by a veth pair: (name, ours, its)."""
    net = os.getpid() % 200 + 20
    name, here, there = f'agvhost{net}', SUBNET.format(net, 1), SUBNET.format(net, 2)
    made = ip('netns', 'add', name)
    if made.returncode != 0:
        pytest.skip(f'no network namespaces here: {made.stderr.strip()}')
    try:
        for args in (('link', 'add', f'veth{net}h', 'type', 'veth', 'peer', 'name',
                      f'veth{net}t'),
                     ('link', 'set', f'veth{net}t', 'netns', name),
                     ('addr', 'add', f'{here}/24', 'dev', f'veth{net}h'),
                     ('link', 'set', f'veth{net}h', 'up'),
                     ('-n', name, 'addr', 'add', f'{there}/24', 'dev', f'veth{net}t'),
                     ('-n', name, 'link', 'set', f'veth{net}t', 'up'),
                     ('-n', name, 'link', 'set', 'lo', 'up')):
            done = ip(*args)
            assert done.returncode == 0, f'ip {" ".join(args)}: {done.stderr}'
        yield name, here, there
    finally:
        ip('netns', 'del', name)  # takes its end of the veth pair, and so both ends


@pytest.mark.dds
@pytest.mark.timeout(420)
def test_a_master_on_this_host_drives_a_truck_whose_graph_runs_on_another(truck_host, tmp_path):
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.mqtt.mosquitto import Mosquitto

    netns, here, _there = truck_host
    domain = os.environ['ROS_DOMAIN_ID']
    with Mosquitto(host=here) as broker:
        url = broker.url
        log = (tmp_path / 'truck.log').open('w+')
        # the truck: its whole graph and world on the other host, on this test's ROS domain
        truck = subprocess.Popen(
            ['ip', 'netns', 'exec', netns, str(BIN / 'agv-launch'), '--vda5050', '--mqtt-url',
             url, '--serial-number', 'agv1', '--time-factor', '1', '--domain-id', domain],
            stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        master = subprocess.Popen(
            [str(BIN / 'dispatcher'), '--ros-args', '-p', f'mqtt_url:={url}',
             '-p', 'trucks:=[agv1]', '-p', 'use_sim_time:=false'],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            start_new_session=True)
        context = Context()
        rclpy.init(context=context)
        node = rclpy.create_node('fleet_host_probe', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        lines: list[str] = []
        node.create_subscription(String, 'fleet/report', lambda m: lines.append(m.data),
                                 qos.EVENTS)
        transport = node.create_publisher(String, 'fleet/transport', qos.EVENTS)

        def said() -> str:
            log.seek(0)
            return log.read()[-3000:]

        def spin_until(condition, limit: float, what: str) -> None:
            deadline = time.monotonic() + limit
            while not condition():
                assert truck.poll() is None, f'the truck graph ended: {said()}'
                assert master.poll() is None, 'the dispatcher ended'
                assert time.monotonic() < deadline, f'no {what}; {lines}\n{said()}'
                executor.spin_once(timeout_sec=0.05)

        try:
            asked = [0.0]

            def answered() -> bool:  # status until the dispatcher answers: both ways matched
                if time.monotonic() - asked[0] > 0.5:
                    transport.publish(String(data='status'))
                    asked[0] = time.monotonic()
                return any(line.startswith('status: ') and 'trucks heard 1' in line
                           for line in lines)

            spin_until(answered, 180, 'state from the truck on the other host')
            # and its world moving, so the task meets a pickup that hears the wire (a task
            # that arrives as the world starts can fail lost_wire: a start-up race of its own)
            spin_until(lambda: 'moving at time_factor' in Path(log.name).read_text(), 120,
                       "the truck's world moving")
            transport.publish(String(data='W0 to W2'))
            spin_until(lambda: 't1: done (agv1)' in lines, 240, 't1 done')
            assert not [line for line in lines if not line.startswith('status: ')
                        and ('failed' in line or 'rejected' in line)]
            # and the truck's DDS graph was never seen from this host, on the same domain
            topics = {name for name, _types in node.get_topic_names_and_types()}
            assert not topics & {'/comms/report', '/traction/status', '/world/pose'}, topics
        finally:
            for proc in (master, truck):
                if proc.poll() is None:
                    os.killpg(proc.pid, signal.SIGINT)
            for proc in (master, truck):
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait(timeout=10)
            executor.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=context)
            log.close()
    assert sys.executable  # the venv's python ran every process (BIN)
