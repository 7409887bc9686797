"""launch/agv_demo.launch.py starts exactly what agv-launch starts (launch is not on PyPI, so
the launch API is stubbed to record what the file asks for)."""

from __future__ import annotations

from pathlib import Path
import runpy
import sys
import types

import pytest
import yaml

from agv_nodes.launcher import Launch, Options, load_graph, node_parameters, realtime_priority
from agv_nodes.records import codec

from conftest import REPO


class Recorded:
    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


class LaunchConfiguration:
    values: dict[str, str] = {}

    def __init__(self, name: str) -> None:
        self.name = name

    def perform(self, context) -> str:
        return self.values[self.name]


@pytest.fixture
def launch_api(monkeypatch):
    modules = {
        'launch': types.SimpleNamespace(LaunchDescription=Recorded),
        'launch.actions': types.SimpleNamespace(DeclareLaunchArgument=Recorded,
                                                OpaqueFunction=Recorded),
        'launch.substitutions': types.SimpleNamespace(LaunchConfiguration=LaunchConfiguration),
        'launch_ros': types.SimpleNamespace(),
        'launch_ros.actions': types.SimpleNamespace(Node=Recorded),
    }
    for name, module in modules.items():
        monkeypatch.setitem(sys.modules, name, module)
    return modules


def nodes_from_launch_file(**overrides) -> list[Recorded]:
    ns = runpy.run_path(str(REPO / 'launch' / 'agv_demo.launch.py'))
    description = ns['generate_launch_description']()
    actions = description.args[0]
    declared = {a.args[0]: a.kwargs['default_value'] for a in actions
                if a.kwargs.get('default_value') is not None}
    LaunchConfiguration.values = {**declared, **overrides}
    opaque = next(a for a in actions if 'function' in a.kwargs)
    return opaque.kwargs['function'](None)


@pytest.mark.parametrize('overrides, options', [
    ({}, Options()),
    ({'namespace': '/agv2', 'world': 'none', 'record_integrity': 'none', 'time_factor': '3.0'},
     Options(namespace='/agv2', world='none', record_integrity='none', time_factor=3.0)),
    ({'bag': '/tmp/agv_launch_file_test_bag'},
     Options(bag=__import__('pathlib').Path('/tmp/agv_launch_file_test_bag'))),
    ({'realtime': '40'}, Options(realtime=40)),
])
def test_launch_file_matches_agv_launch(launch_api, overrides, options):
    nodes = nodes_from_launch_file(**overrides)
    launch = Launch(options)
    expected = launch.specs()
    assert [n.kwargs['name'] for n in nodes] == [s.name for s in expected]
    graph = load_graph()
    for node, spec in zip(nodes, expected, strict=True):
        assert node.kwargs['package'] == 'agv_nodes'
        assert node.kwargs['executable'] == spec.executable
        assert node.kwargs['namespace'] == options.namespace
        params_file, params = node.kwargs['parameters']
        assert params_file == str(graph.parameters)
        assert params == node_parameters(graph, spec, options)
        prio = realtime_priority(spec, options)
        assert node.kwargs['prefix'] == (f'chrt -f {prio}' if prio else None)
        assert prio == (40 if options.realtime and spec.realtime else 0)
        # and agv-launch passes the same values, in a second parameter file after the first
        cmd = launch.command(spec)
        child = launch.child_command(spec)  # and the same priority, to launch_child
        between = child[child.index('agv_nodes.launch_child') + 2:child.index(cmd[0])]
        assert between == (['--sched-fifo', str(prio)] if prio else [])
        files = [cmd[i + 1] for i, c in enumerate(cmd) if c == '--params-file']
        assert files[0] == str(graph.parameters)
        second = yaml.safe_load(Path(files[1]).read_text())
        assert second == {f'/**/{spec.name}': {'ros__parameters': params}}
    launch.stop()


def test_every_node_script_is_in_the_graph():
    import ast

    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    kw = {k.arg: k.value for k in call.keywords}
    scripts = [e.split('=')[0].strip() for e in ast.literal_eval(kw['entry_points'])[
        'console_scripts'] if not e.startswith('agv-')]
    assert sorted(scripts) == sorted(n.executable for n in load_graph().nodes)


def test_launch_overrides_beat_the_parameter_file():
    """`agv-launch -p executive:status_timeout:=9.0` wins over the file's `/**/executive:` entry.

    Checked with the real rcl argument parser: a node built from the exact command line.
    (A plain `-p status_timeout:=9.0` loses to the node-specific file entry with rclpy 7.1.)
    """
    import rclpy
    from rclpy.context import Context

    graph = load_graph()
    filed = yaml.safe_load(graph.parameters.read_text())['/**/executive']['ros__parameters']
    assert filed['status_timeout'] != 9.0  # the file sets its own value
    launch = Launch(Options(extra={'executive': ['status_timeout:=9.0', "srm_map:=['2:10']"]}))
    cmd = launch.command(graph.node('executive'))
    context = Context()
    rclpy.init(args=['executive', *cmd[cmd.index('--ros-args'):]], context=context)
    try:
        node = rclpy.create_node('executive', context=context)
        node.declare_parameter('status_timeout', 0.3)
        node.declare_parameter('srm_map', [''])
        assert node.get_parameter('status_timeout').value == 9.0
        assert node.get_parameter('srm_map').value == ['2:10']
        assert node.get_parameter('use_sim_time').value is True
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
        launch.stop()


@pytest.mark.parametrize('text, words', [
    ('adc_snapshot:loss=0.1', 'not a record a node of the graph writes'),
    ('traction_link:loss=2', "'loss=2'"),
    ('traction_link:jitter=0.1', "'jitter=0.1'"),
    ('traction_link:', 'nothing to inject'),
])
def test_bad_fault_option_names_the_problem(text, words):
    from agv_nodes.launcher import GraphError, load_graph, parse_fault

    with pytest.raises(GraphError, match='--fault') as err:
        parse_fault(text, load_graph())
    assert words in str(err.value)


def test_fault_option_reaches_the_writer_and_the_world():
    from agv_nodes.launcher import Options, load_graph, node_parameters, parse_fault

    graph = load_graph()
    record, spec = parse_fault('traction_link:loss=0.1,delay=0.02', graph)
    options = Options(faults={record: spec})
    nav = node_parameters(graph, graph.node('navigation'), options)
    assert (nav['fault_record'], nav['fault_loss'], nav['fault_delay']) == \
        ('traction_link', 0.1, 0.02)
    assert 'fault_record' not in node_parameters(graph, graph.node('traction'), options)
    world = node_parameters(graph, graph.node('world'), options)
    assert 'traction_link' in world['pace_on'] and world['pace_slack'] == ['traction_link:0.09']
    assert 'pace_slack' not in node_parameters(graph, graph.node('world'), Options())


def test_world_waits_for_every_link_whose_two_ends_are_launched():
    """wait_for_links: each reader of each record once both ends run (LinkAnnouncer), and each
    writer's end with as many readers as the world waits for on its topic."""
    from dataclasses import replace

    from agv_nodes.launcher import wait_links, wait_lists
    from agv_nodes.ros_ports import parse_links
    from agv_nodes.world.node import parse_link_entry

    graph = load_graph()
    links = wait_links(graph, recording=True)
    assert {'navigation:position_sensor_status', 'position_sensor:adc_snapshot',
            'traction:traction_command', 'executive:navigation_status',
            'world:traction_drive'} <= set(links)
    # the writer's end: navigation, the world's pacing reader and the recorder
    assert 'position_sensor>position_sensor_status:3' in links
    assert 'world>adc_snapshot:2' in links and 'world>wheel_odometry:4' in links
    subs, _pubs = wait_lists(graph, True, True)
    topics = {codec()[name].topic: name for name in codec().names()}
    for entry in subs:  # the same reader counts as wait_for_subscribers
        topic, _, n = entry.partition(':')
        name = topics[topic]
        assert f'{codec()[name].writer}>{name}:{n or 1}' in links
    assert all(parse_link_entry(entry) is not None for entry in links)
    assert parse_link_entry('navigation>nonsense:2') is None
    assert parse_link_entry('navigation>navigation_status:x') is None
    assert parse_link_entry('navigation>navigation_status:0') is None
    assert parse_links('navigation position_sensor_status navigation_status>3') == (
        'navigation', {'position_sensor_status'}, {'navigation_status': 3})
    assert node_parameters(graph, graph.node('world'), Options())['wait_for_links'] == \
        wait_links(graph, recording=False)
    assert node_parameters(graph, graph.node('world'), Options(bag=Path('b')))[
        'wait_for_links'] == links
    partial = replace(graph, nodes=[n for n in graph.nodes if n.name != 'position_sensor'])
    assert not [x for x in wait_links(partial)
                if x.startswith('position_sensor') or 'position_sensor_status' in x]
    assert 'navigation:wheel_odometry' in wait_links(partial)


def test_demo_waits_until_every_link_has_carried_a_record():
    """agv-demo sends the programme only once each reader's /diagnostics inputs row shows a
    record accepted on each of its links (the world's pacing readers are not in its row)."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from agv_nodes.demo import inputs_accepted, silent_links
    from agv_nodes.launcher import wait_links

    def row(name: str, **accepted: int) -> DiagnosticStatus:
        values = [KeyValue(key=f'{k} accepted', value=str(v)) for k, v in accepted.items()]
        values.append(KeyValue(key='rejected', value='0'))
        return DiagnosticStatus(name=name, values=values)

    links = wait_links(load_graph(), recording=True)
    msg = DiagnosticArray(status=[
        row('agv/navigation/inputs', navigation_command=19, position_sensor_status=0,
            wheel_odometry=101),
        row('agv/world/inputs', traction_drive=98, steering_command=98, conveyor_command=19),
        row('agv/executive/display')])
    accepted = inputs_accepted(msg)
    assert accepted['navigation'] == {'navigation_command': 19, 'position_sensor_status': 0,
                                      'wheel_odometry': 101}
    silent = silent_links(links, accepted)
    assert 'navigation:position_sensor_status' in silent  # nothing yet on the sensor's link
    assert 'navigation:wheel_odometry' not in silent
    assert not [x for x in silent if x.startswith('world:')]  # pacing readers: not in its row
    assert 'position_sensor:adc_snapshot' in silent  # not heard from yet
    assert not [x for x in silent if '>' in x]
    every = {link.partition(':')[0]: {} for link in links if '>' not in link}
    for link in links:
        node, sep, record = link.partition(':')
        if sep and '>' not in node:
            every[node][record] = 1
    assert silent_links(links, every) == []


@pytest.mark.parametrize('options, words', [
    (Options(realtime=100), '1-99'),
    (Options(realtime=-3), '1-99'),
    (Options(realtime=20, time_factor=0.0), 'time factor > 0'),
])
def test_bad_realtime_option_names_the_problem(options, words):
    from agv_nodes.launcher import GraphError

    with pytest.raises(GraphError, match='--realtime') as err:
        Launch(options)
    assert words in str(err.value)


def test_graph_realtime_flag_must_be_true_or_false(tmp_path):
    from agv_nodes.launcher import GraphError

    doc = yaml.safe_load((REPO / 'config' / 'graph.yaml').read_text())
    doc['nodes'][1]['realtime'] = 'yes please'
    bad = tmp_path / 'graph.yaml'
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(GraphError, match=r'nodes\[1\]\.realtime') as err:
        load_graph(bad)
    assert str(bad) in str(err.value) and 'yes please' in str(err.value)


def test_realtime_marks_the_sensor_to_traction_chain():
    graph = load_graph()
    assert {n.name for n in graph.nodes if n.realtime} == {
        'world', 'position_sensor', 'navigation', 'traction'}


def test_launch_child_takes_the_priority_it_is_given():
    """launch_child --sched-fifo N: the exec'd node runs SCHED_FIFO at N, or, where this user
    may not, launch_child refuses with a message and status 2 (and agv-launch refuses first)."""
    import os
    import subprocess

    from agv_nodes.launcher import GraphError, check_realtime

    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    try:
        check_realtime(Options(realtime=3))
        allowed = True
    except GraphError as exc:
        assert 'SCHED_FIFO' in str(exc)
        allowed = False
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    probe = ('import os; p = os.sched_getparam(0); '
             'print(os.sched_getscheduler(0), p.sched_priority)')
    run = subprocess.run([sys.executable, '-m', 'agv_nodes.launch_child', str(os.getpid()),
                          '--sched-fifo', '3', sys.executable, '-c', probe],
                         capture_output=True, text=True, timeout=60)
    if allowed:
        assert run.returncode == 0, run.stderr
        assert run.stdout.split() == [str(os.SCHED_FIFO), '3']
    else:
        assert run.returncode == 2 and 'SCHED_FIFO priority 3 refused' in run.stderr
    plain = subprocess.run([sys.executable, '-m', 'agv_nodes.launch_child', str(os.getpid()),
                            sys.executable, '-c', probe], capture_output=True, text=True,
                           timeout=60)
    assert plain.stdout.split() == [str(os.SCHED_OTHER), '0']
