"""Discovery on one host past 32 participants (agv_nodes.discovery, config/dds/).

Every process of a graph is a DDS participant. With ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
rmw_fastrtps announces each to the first 32 participant ports of the domain, so two
participants that both started after 32 others never meet: a fleet of four trucks (36
processes) lost its world's /clock that way and never moved. The launcher's profile announces to
120. Here one process stands in for a crowded graph: every rclpy context is a participant of
its own, so 34 contexts fill the first 34 participant ids, then a writer and a reader come last.
Fast DDS reads its profile once per process, so each configuration runs in a process of its own.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from agv_nodes.discovery import PARTICIPANTS, localhost_environment, use_localhost_discovery

pytestmark = [pytest.mark.dds]

CROWD = 34  # participants started before the two that must meet

LATE_PAIR = f"""
import sys
import time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import String

crowd = []
for k in range({CROWD}):
    context = rclpy.Context()
    rclpy.init(context=context)
    crowd.append(rclpy.create_node(f'crowd{{k}}', context=context))
nodes = {{}}
for name in ('late_writer', 'late_reader'):
    context = rclpy.Context()
    rclpy.init(context=context)
    nodes[name] = rclpy.create_node(name, context=context)
executor = SingleThreadedExecutor(context=nodes['late_reader'].context)
executor.add_node(nodes['late_reader'])
got = []
nodes['late_reader'].create_subscription(String, 'late', lambda m: got.append(m.data), 10)
pub = nodes['late_writer'].create_publisher(String, 'late', 10)
start = time.monotonic()
while time.monotonic() - start < float(sys.argv[1]) and not got:
    if pub.get_subscription_count():
        pub.publish(String(data='heard'))
    executor.spin_once(timeout_sec=0.1)
print('delivered' if got else 'not delivered')
"""


def late_pair(env: dict[str, str], limit: float) -> str:
    """Run the crowd and the late pair with `env`; return what the reader got."""
    run = subprocess.run([sys.executable, '-c', LATE_PAIR, str(limit)], env=env,
                         capture_output=True, text=True, timeout=limit + 90)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout.strip().splitlines()[-1]


@pytest.mark.timeout(240)
def test_two_participants_after_a_crowd_of_34_meet_with_the_launchers_discovery():
    env = dict(os.environ)
    use_localhost_discovery(env)
    assert PARTICIPANTS > CROWD + 2
    assert late_pair(env, limit=60.0) == 'delivered'
    # The cause, shown: with rmw_fastrtps's own localhost range the same pair never meets.
    env = {k: v for k, v in os.environ.items() if k not in localhost_environment()}
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    assert late_pair(env, limit=15.0) == 'not delivered'


def test_the_launcher_gives_every_node_the_localhost_profile(tmp_path):
    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch

    launch = Launch(Options(time_factor=1.0, log_dir=tmp_path, quiet=True))
    try:
        assert launch.env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
        profile = launch.env['FASTRTPS_DEFAULT_PROFILES_FILE']
        assert os.path.isfile(profile) and 'localhost_discovery.xml' in profile
        text = open(profile).read()
        assert f'<maxInitialPeersRange>{PARTICIPANTS}</maxInitialPeersRange>' in text
        assert '<address>127.0.0.1</address>' in text
    finally:
        launch.stop(timeout=1.0)
