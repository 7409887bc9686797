"""A node process's start and end.

A bad parameter value or file stops it at start-up with one line naming file, key, value; its
teardown at the end is bounded.
"""

from __future__ import annotations

from pathlib import Path
import subprocess

import pytest

from conftest import PYTHON, REPO

BIN = Path(PYTHON).parent


@pytest.mark.parametrize('node, key, value, words', [
    ('traction', 'record_integrity', 'maybe', "not one of ['e2e', 'none']"),
    ('traction', 'command_timeout', '-1.0', 'outside'),
    ('traction', 'control', 'fuzzy_logic', 'not one of'),
    ('traction', 'comand_timeout', '0.1', 'unknown parameter'),  # a typo is not ignored
    ('position_sensor', 'white', '[1, 2]', 'needs exactly 8 values'),
    ('position_sensor', 'min_consecutive_matches', '0', 'min_consecutive_matches'),
    ('navigation', 'stopping', 'anchor', 'not one of'),
    ('route_following', 'wire.kp', 'fast', 'must be a number'),
    ('executive', 'srm_map', "['1:99']", '1:99'),
    ('executive', 'status_timout', '0.1', 'unknown parameter'),
    ('communications', 'locations', '[0.5]', 'must be an integer'),
    ('world', 'layout', 'atlantis', 'atlantis.yaml'),
    ('world', 'time_factor', '-2.0', 'outside 0.0..1000.0'),
    ('world', 'pace_on', "['adc_snapshot']", 'unknown parameter'),
    ('world', 'trucks', "['agv1', 'agv1']", 'named twice'),
    ('world', 'trucks', "['agv1', 'agv2', 'agv3', 'agv4']", '4 trucks need a stop marker each'),
    ('world', 'set_down', "['L0']", "'L0' is no stop marker of layout demo_1983"),
    ('recorder', 'bag', str(REPO), 'exists already'),
])
def test_bad_parameter_file_stops_start_up(tmp_path, node, key, value, words):
    params = tmp_path / 'bad_params.yaml'
    params.write_text(f'/**/{node}:\n  ros__parameters:\n    {key}: {value}\n')
    res = subprocess.run([str(BIN / node), '--ros-args', '--params-file', str(params)],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2, res.stdout + res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert str(params) in line and repr(key) in line and words in line
    assert 'Traceback' not in res.stderr


@pytest.mark.parametrize('text, line_no, words', [
    ('/**/traction:\n  ros__parameters:\n    kp: [1, 2\n', None, 'not YAML'),
    # YAML itself keeps the last of two: a typo-free duplicate must not silently win either
    ('/**/traction:\n  ros__parameters:\n    command_timeout: 0.15\n'
     '    command_timeout: 0.3\n', 4, "key 'command_timeout' given twice"),
], ids=['unparsable', 'duplicate-key'])
def test_a_bad_yaml_parameter_file_names_the_file_and_line(tmp_path, text, line_no, words):
    params = tmp_path / 'broken.yaml'
    params.write_text(text)
    res = subprocess.run([str(BIN / 'traction'), '--ros-args', '--params-file', str(params)],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2, res.stdout + res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert line.startswith(f'{params}: line {line_no or ""}') and words in line, res.stderr


def test_an_unknown_parameter_on_the_command_line_stops_the_node():
    res = subprocess.run([str(BIN / 'navigation'), '--ros-args', '-p', 'stoping:=controlled'],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "unknown parameter 'stoping'" in res.stderr.strip().splitlines()[-1]


@pytest.mark.dds
@pytest.mark.timeout(240)
def test_the_harness_and_the_launched_graph_run_with_the_same_settings():
    """The lock-step harness builds every core exactly as the launched nodes are built.

    Both take the graph's parameter file and the layout: every setting is compared, queried
    from each running node.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import parameter_value_to_python
    from rclpy.parameter_client import AsyncParameterClient

    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch
    from agv_nodes.harness import truck
    from agv_nodes.settings import values_of

    h = truck('demo_1983')
    expected = {name: values_of(core.p) for name, core in h.cores.items()}
    expected['world'] = values_of(h.world.p)
    launch = Launch(Options(quiet=True))
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('settings_probe', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    launch.start()
    try:
        for name, want in expected.items():
            client = AsyncParameterClient(node, name)
            assert client.wait_for_services(timeout_sec=60), name
            # A service reply sent before the node's reply writer matched this client's reader
            # is lost (the request side can match first): ask again rather than wait on it.
            for _attempt in range(4):
                future = client.get_parameters(list(want))
                executor.spin_until_future_complete(future, timeout_sec=10)
                if future.done():
                    break
            assert future.done(), f'{name}: no parameter reply to four requests'
            values = future.result().values
            assert len(values) == len(want), (name, len(values), len(want))
            got = {key: parameter_value_to_python(v) for key, v in zip(want, values,
                                                                         strict=True)}
            got = {key: list(v) if not isinstance(v, (str, bool, int, float)) else v
                   for key, v in got.items()}
            assert got == want, (name, {k: (got[k], want[k]) for k in want
                                        if got[k] != want[k]})
    finally:
        launch.stop()
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def test_shipped_parameter_file_is_valid_for_every_node(tmp_path):
    """Every node starts with config/agv_demo.yaml (and stops at once: duration / SIGINT).

    The recorder is given its bag and the VDA 5050 bridge a broker, as the launch gives them.
    """
    from agv_nodes.graph.model import load_graph
    from agv_nodes.mqtt.broker import local_broker  # mosquitto, as the launch runs it

    graph = load_graph()
    with local_broker() as broker:
        _start_every_node(graph, {'recorder': ['-p', f'bag:={tmp_path / "bag"}'],
                                  'bridge': ['-p', f'mqtt_url:={broker.url}'],
                                  'master': ['-p', f'mqtt_url:={broker.url}'],
                                  'viewer': ['-p', 'port:=0']})


def _start_every_node(graph, given: dict[str, list[str]]) -> None:
    import os
    import signal
    import time

    import rclpy
    from rclpy.context import Context

    procs = []
    try:
        for spec in graph.nodes:
            extra = given.get(spec.role, [])
            procs.append((spec.name, subprocess.Popen(
                [str(BIN / spec.executable), '--ros-args', '--params-file',
                 str(graph.parameters), '-p', 'use_sim_time:=true', *extra],
                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)))
        # up = its node is in the ROS graph (a fixed sleep interrupted a slow start-up)
        context = Context()
        rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
        probe = rclpy.create_node('parameter_file_probe', context=context)
        try:
            deadline = time.monotonic() + 90.0
            while missing := {n for n, _ in procs} - set(probe.get_node_names()):
                for name, proc in procs:
                    assert proc.poll() is None, f'{name} exited: {proc.stdout.read()}'
                assert time.monotonic() < deadline, f'not up within 90 s: {sorted(missing)}'
                time.sleep(0.1)
        finally:
            probe.destroy_node()
            rclpy.shutdown(context=context)
        for _name, proc in procs:
            proc.send_signal(signal.SIGINT)
        for name, proc in procs:
            out, _ = proc.communicate(timeout=30)
            assert proc.returncode == 0, f'{name}: {out[-2000:]}'
    finally:  # a failure midway leaves no node on the session's domain for the next tests
        for _name, proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait(10)


_TEARDOWN = '''
import sys, time
from agv_nodes.node_process import _teardown

class Stuck:
    """A node whose entities never go (as Fast DDS's deletion once hung)."""

    def get_name(self):
        return 'stuck_node'

    def finish(self):
        print('bag closed', flush=True)

    def destroy_node(self):
        time.sleep(600)

_teardown(Stuck(), None, code=int(sys.argv[1]), limit=0.5)
print('not reached')
'''


@pytest.mark.parametrize('code', [0, 2])
def test_a_teardown_stuck_in_dds_ends_the_process_with_its_status(code):
    """spin_main's teardown is bounded.

    The node's own finish() runs first and in full, then past the limit the process says so,
    dumps its stacks and exits with the node's status.
    """
    res = subprocess.run([PYTHON, '-c', _TEARDOWN, str(code)], capture_output=True, text=True,
                         timeout=60, cwd=REPO)
    assert res.returncode == code, res.stderr
    assert res.stdout == 'bag closed\n'
    assert 'stuck_node: DDS teardown still blocked after 0.5 s; exiting without it' in res.stderr
    assert 'in destroy_node' in res.stderr  # the stuck thread's stack, for the next diagnosis
