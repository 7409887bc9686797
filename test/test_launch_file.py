"""launch/agv_demo.launch.py starts exactly what agv-launch starts.

launch is not on PyPI, so the launch API is stubbed to record what the file asks for.
"""

from __future__ import annotations

from pathlib import Path
import runpy
import sys
import types

import pytest
import yaml

from agv_nodes.graph.model import GraphError, load_graph
from agv_nodes.graph.parameters import (
    Options,
    check_realtime,
    node_parameters,
    paced_nodes,
    parse_fault,
    realtime_priority,
    wait_links,
)
from agv_nodes.graph.supervisor import CHILD, Launch
from agv_nodes.records import codec
from agv_nodes.sim_progress import LINK as PROGRESS

from conftest import REPO


class Recorded:
    def __init__(self, *args, **kwargs) -> None:
        self.args, self.kwargs = args, kwargs


class Process(Recorded):
    """An ExecuteProcess: a process that is not a node (the MQTT broker)."""


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
                                                ExecuteProcess=Process,
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
    ({'vda5050': 'true'}, Options(vda5050=True)),
    ({'vda5050': 'true', 'mqtt_url': 'mqtt://10.0.0.5', 'namespace': '/agv3'},
     Options(vda5050=True, mqtt_url='mqtt://10.0.0.5', namespace='/agv3')),
    ({'foxglove': '9000'}, Options(foxglove=9000)),
])
def test_launch_file_matches_agv_launch(launch_api, monkeypatch, overrides, options):
    """Same nodes, same parameters, the same priority.

    But for the bridge's broker when none is named: the launch file starts one on port 1883,
    agv-launch its embedded one on a free port.
    """
    from dataclasses import replace

    monkeypatch.delenv('AGV_MQTT_URL', raising=False)
    actions = nodes_from_launch_file(**overrides)
    nodes = [a for a in actions if not isinstance(a, Process)]
    broker = [a.kwargs['cmd'] for a in actions if isinstance(a, Process)]
    launch = Launch(options)
    expected = launch.specs()
    assert [n.kwargs['name'] for n in nodes] == [s.name for s in expected]
    graph = load_graph()
    if options.vda5050 and options.mqtt_url is None:
        assert broker == [['python3', '-m', 'agv_nodes.mqtt.broker', '--port', '1883']]
        assert launch.broker is not None and launch.mqtt_url.startswith('mqtt://127.0.0.1:')
        file_url = 'mqtt://127.0.0.1:1883'
    else:
        assert broker == [] and launch.broker is None
        file_url = launch.mqtt_url  # the same broker, named the same way
    for node, spec in zip(nodes, expected, strict=True):
        assert node.kwargs['package'] == 'agv_nodes'
        assert node.kwargs['executable'] == spec.executable
        assert node.kwargs['namespace'] == options.namespace
        params_file, params = node.kwargs['parameters']
        assert params_file == str(graph.parameters)
        assert params == node_parameters(graph, spec, replace(options, mqtt_url=file_url))
        prio = realtime_priority(spec, options)
        assert node.kwargs['prefix'] == (f'chrt -f {prio}' if prio else None)
        assert prio == (40 if options.realtime and spec.realtime else 0)
        # and agv-launch passes the same values, in a second parameter file after the first
        cmd = launch.command(spec)
        child = launch.child_command(spec)  # and the same priority, to the child wrapper
        between = child[child.index(CHILD) + 2:child.index(cmd[0])]
        assert between == (['--sched-fifo', str(prio)] if prio else [])
        files = [cmd[i + 1] for i, c in enumerate(cmd) if c == '--params-file']
        assert files[0] == str(graph.parameters)
        second = yaml.safe_load(Path(files[1]).read_text())
        # ... but for the world's ready file, agv-launch's signal that time has started
        ready = {'ready_file': str(launch.ready_file)} if spec.role == 'world' else {}
        url = {'mqtt_url': launch.mqtt_url} if spec.role == 'bridge' else {}
        assert 'ready_file' not in params
        assert second == {f'/**/{spec.name}': {'ros__parameters': {**params, **ready, **url}}}
    launch.stop()
    assert launch.broker is None or launch.broker.port is None  # stopped with the launch


def test_every_node_script_is_in_the_graph():
    import ast

    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    kw = {k.arg: k.value for k in call.keywords}
    scripts = [e.split('=')[0].strip() for e in ast.literal_eval(kw['entry_points'])[
        'console_scripts'] if not e.startswith('agv-')]
    assert sorted(scripts) == sorted(n.executable for n in load_graph().nodes)


def test_launch_overrides_beat_the_parameter_file(tmp_path):
    """`agv-launch -p executive:status_timeout:=9.0` wins over a file's `/**/executive:` entry.

    Checked with the real rcl argument parser: a node built from the exact command line, with
    a parameter file of the test's own (what the shipped file sets is its business).
    """
    import rclpy
    from rclpy.context import Context

    graph = load_graph()
    filed = tmp_path / 'params.yaml'
    filed.write_text('/**/executive:\n  ros__parameters:\n    status_timeout: 0.5\n')
    launch = Launch(Options(params=filed, extra={'executive': ['status_timeout:=9.0',
                                                               "srm_map:=['2:10']"]}))
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
    with pytest.raises(GraphError, match='--fault') as err:
        parse_fault(text, load_graph())
    assert words in str(err.value)


def test_fault_option_reaches_the_writer_only():
    """A fault is injected at the record's writer; the world is told nothing about it.

    The world paces on each node's sim progress, not on its records.
    """
    graph = load_graph()
    record, spec = parse_fault('traction_link:loss=0.1,delay=0.02', graph)
    options = Options(faults={record: spec})
    nav = node_parameters(graph, graph.node('navigation'), options)
    assert (nav['fault_record'], nav['fault_loss'], nav['fault_delay']) == \
        ('traction_link', 0.1, 0.02)
    assert 'fault_record' not in node_parameters(graph, graph.node('traction'), options)
    assert node_parameters(graph, graph.node('world'), options) == \
        node_parameters(graph, graph.node('world'), Options())


def test_world_waits_for_every_link_whose_two_ends_are_launched():
    """wait_for_links names every link the world waits for.

    Each reader of each record once both ends run (LinkAnnouncer), each writer's end with all
    its readers, and each paced node's progress writer.
    """
    from dataclasses import replace

    from agv_nodes.ros_ports import parse_links

    graph = load_graph()
    links = wait_links(graph, recording=True)
    assert {'navigation:position_sensor_status', 'position_sensor:adc_snapshot',
            'traction:traction_command', 'executive:navigation_status',
            'world:traction_drive'} <= set(links)
    # the writer's end: the schema's readers and the recorder, nothing else
    assert 'position_sensor>position_sensor_status:2' in links
    assert 'world>adc_snapshot:2' in links and 'world>wheel_odometry:4' in links
    # the world reads only what its schemas say it reads
    assert sorted(x for x in links if x.startswith('world:')) == [
        'world:conveyor_command', 'world:steering_command', 'world:traction_drive']
    assert not [x for x in links if PROGRESS in x]  # no paced nodes named: no progress links
    for entry in links:  # each entry is NODE:RECORD or NODE>RECORD:N, of a real link
        if '>' in entry:
            node, _, rest = entry.partition('>')
            record, _, count = rest.partition(':')
            assert codec()[record].writer == node and int(count) >= 1, entry
        else:
            node, _, record = entry.partition(':')
            assert node in codec()[record].readers, entry
    assert parse_links('navigation position_sensor_status navigation_status>3') == (
        'navigation', {'position_sensor_status'}, {'navigation_status': 3})
    partial = replace(graph, nodes=[n for n in graph.nodes if n.name != 'position_sensor'])
    assert not [x for x in wait_links(partial, paced=['position_sensor', 'navigation'])
                if x.startswith('position_sensor') or 'position_sensor_status' in x]
    assert f'world>{PROGRESS}:1' not in wait_links(graph, paced=['world'])  # nodes only
    assert 'navigation:wheel_odometry' in wait_links(partial)


def test_world_paces_on_every_node_by_its_sim_progress():
    """With a simulated world on sim time the world paces on every node's sim progress.

    Every node publishes its sim progress and the world paces on all of them, once each
    progress writer has matched it; on wall time neither.
    """
    graph = load_graph()
    nodes = sorted(n.name for n in graph.nodes if n.role == 'node')
    for options in (Options(), Options(bag=Path('b'), time_factor=0.0)):
        world = node_parameters(graph, graph.node('world'), options)
        assert world['pace_nodes'] == nodes
        assert world['wait_for_links'] == wait_links(graph, options.bag is not None, nodes)
        assert {f'{n}>{PROGRESS}:1' for n in nodes} <= set(world['wait_for_links'])
        assert not {'pace_on', 'pace_slack', 'wait_for_subscribers', 'wait_for_publishers',
                    'ready_file'} & set(world)
        assert all(node_parameters(graph, graph.node(n), options)['sim_progress']
                   for n in nodes)
    wall = Options(use_sim_time=False)
    world = node_parameters(graph, graph.node('world'), wall)
    assert world['pace_nodes'] == [] and world['publish_clock'] is False
    assert world['wait_for_links'] == wait_links(graph) and PROGRESS not in str(world)
    for options in (wall, Options(world='none')):
        assert not any(node_parameters(graph, graph.node(n), options)['sim_progress']
                       for n in nodes)
    for spec in graph.nodes:
        if spec.role != 'node':
            assert 'sim_progress' not in node_parameters(graph, spec, Options())
    ready = node_parameters(graph, graph.node('world'), Options(), Path('/tmp/x/world.ready'))
    assert ready['ready_file'] == '/tmp/x/world.ready'


def test_launch_is_moving_once_the_world_writes_its_ready_file():
    """agv-launch knows time has started from the world's ready file, not from its log."""
    import threading

    launch = Launch(Options(quiet=True))
    try:
        assert launch.ready_file.parent.is_dir() and not launch.ready_file.exists()
        assert not launch.moving.is_set()
        assert launch.moving.wait(0.05) is False
        threading.Timer(0.1, launch.ready_file.write_text, ['moving\n']).start()
        assert launch.moving.wait(10.0) is True
        assert launch.moving.is_set()
    finally:
        launch.stop()
    assert not launch.ready_file.exists() and launch.moving.is_set()  # stays set


def test_demo_waits_until_every_link_has_carried_a_record():
    """agv-demo sends the programme only once every link has carried a record.

    That is once each reader's /diagnostics inputs row shows a record accepted on each of its
    links (writers' ends are not in a reader's row).
    """
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from agv_nodes.demo import inputs_accepted, silent_links

    def row(name: str, **accepted: int) -> DiagnosticStatus:
        values = [KeyValue(key=f'{k} accepted', value=str(v)) for k, v in accepted.items()]
        values.append(KeyValue(key='rejected', value='0'))
        return DiagnosticStatus(name=name, values=values)

    graph = load_graph()
    links = wait_links(graph, recording=True, paced=paced_nodes(graph, Options()))
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
    assert not [x for x in silent if x.startswith('world:')]  # all three accepted
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
    with pytest.raises(GraphError, match='--realtime') as err:
        Launch(options)
    assert words in str(err.value)


def test_graph_realtime_flag_must_be_true_or_false(tmp_path):
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


def test_child_takes_the_priority_it_is_given():
    """graph.child --sched-fifo N: the exec'd node runs SCHED_FIFO at N, or is refused.

    Where this user may not, the child refuses with a message and status 2 (and agv-launch
    refuses first).
    """
    import os
    import subprocess

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
    run = subprocess.run([sys.executable, '-m', CHILD, str(os.getpid()),
                          '--sched-fifo', '3', sys.executable, '-c', probe],
                         capture_output=True, text=True, timeout=60)
    if allowed:
        assert run.returncode == 0, run.stderr
        assert run.stdout.split() == [str(os.SCHED_FIFO), '3']
    else:
        assert run.returncode == 2 and 'SCHED_FIFO priority 3 refused' in run.stderr
    plain = subprocess.run([sys.executable, '-m', CHILD, str(os.getpid()),
                            sys.executable, '-c', probe], capture_output=True, text=True,
                           timeout=60)
    assert plain.stdout.split() == [str(os.SCHED_OTHER), '0']


def test_vda5050_options_reach_the_bridge(monkeypatch):
    """--vda5050, --mqtt-url and --serial-number end up as the bridge's parameters.

    The serial number comes from the namespace unless given; an explicit URL wins over
    AGV_MQTT_URL, which wins over the embedded broker; the world waits for the bridge on no
    link (it is not a record node), and options that cannot work are refused before anything
    starts.
    """
    from agv_nodes.graph.cli import build_parser, options_from
    from agv_nodes.graph.parameters import serial_number

    assert serial_number(Options()) == 'agv1'
    assert serial_number(Options(namespace='/agv2')) == 'agv2'
    assert serial_number(Options(namespace='/fleet/agv2/')) == 'fleetagv2'
    assert serial_number(Options(namespace='/agv2', serial_number='truck_7')) == 'truck_7'
    args = build_parser().parse_args(['--vda5050', '--namespace', '/agv2',
                                      '--mqtt-url', 'mqtt://10.1.2.3:1884'])
    options = options_from(args)
    assert (options.vda5050, options.mqtt_url, options.serial_number) == \
        (True, 'mqtt://10.1.2.3:1884', '')
    assert options_from(build_parser().parse_args([])).vda5050 is False

    graph = load_graph()
    monkeypatch.setenv('AGV_MQTT_URL', 'mqtt://broker.example')
    for given, url in (('mqtt://10.1.2.3:1884', 'mqtt://10.1.2.3:1884'),
                       (None, 'mqtt://broker.example:1883')):
        launch = Launch(Options(vda5050=True, mqtt_url=given, namespace='/agv2', quiet=True))
        try:
            assert (launch.mqtt_url, launch.broker) == (url, None)  # no broker of our own
            names = [s.name for s in launch.specs()]
            assert names.index('vda5050_bridge') == names.index('communications') + 1
            bridge = graph.node('vda5050_bridge')
            params = node_parameters(graph, bridge, launch.o)
            assert params == {'use_sim_time': True, 'layout': 'demo_1983',
                              'serial_number': 'agv2', 'mqtt_url': url}
            world = graph.node('world')
            assert node_parameters(graph, world, launch.o) == \
                node_parameters(graph, world, Options())  # nothing waits for the bridge
        finally:
            launch.stop()
    plain = Launch(Options())
    assert 'vda5050_bridge' not in [s.name for s in plain.specs()] and plain.mqtt_url is None
    plain.stop()
    assert 'vda5050_bridge' not in paced_nodes(graph, Options(vda5050=True))
    assert not [x for x in wait_links(graph, True, paced_nodes(graph, Options()))
                if 'vda5050' in x]

    for options, words in (
            (Options(mqtt_url='mqtt://10.1.2.3'), '--mqtt-url is for the VDA 5050 bridge'),
            (Options(serial_number='agv9'), '--serial-number is for the VDA 5050 bridge'),
            (Options(vda5050=True, serial_number='agv/9'), "--serial-number 'agv/9'"),
            (Options(vda5050=True, mqtt_url='http://10.1.2.3'), "--mqtt-url 'http://"),
            (Options(vda5050=True, layout='tape_1991'), 'concic2 truck')):
        with pytest.raises(GraphError, match=words):
            Launch(options)


def test_launch_file_starts_a_fleet_as_agv_launch_does(launch_api, monkeypatch):
    """trucks:=2: the same processes in the same namespaces, the floor's file for the world."""
    from dataclasses import replace

    from agv_nodes.graph.parameters import floor_parameters

    monkeypatch.delenv('AGV_MQTT_URL', raising=False)
    url = 'mqtt://10.0.0.5:1883'
    actions = nodes_from_launch_file(trucks='2', vda5050='true', mqtt_url=url)
    nodes = [a for a in actions if not isinstance(a, Process)]
    options = Options(trucks=2, vda5050=True, mqtt_url=url)
    launch = Launch(options)
    try:
        units = launch.units()
        assert [(n.kwargs['name'], n.kwargs['namespace']) for n in nodes] == \
            [(spec.name, ns) for _label, spec, ns in units]
        graph = launch.graph
        for node, (_label, spec, ns) in zip(nodes, units, strict=True):
            params_file, params = node.kwargs['parameters']
            own = replace(launch.o, namespace=ns)
            if spec.role == 'world':  # a file with the floor's node and each truck's
                assert yaml.safe_load(Path(params).read_text()) == \
                    floor_parameters(graph, spec, own)
                Path(params).unlink()
            else:
                assert params == node_parameters(graph, spec, own)
    finally:
        launch.stop()


def test_rviz_argument_starts_rviz_with_the_shipped_configuration(launch_api):
    nodes = nodes_from_launch_file(rviz='true')
    (rviz,) = [n for n in nodes if n.kwargs.get('executable') == 'rviz2']
    config = Path(rviz.kwargs['arguments'][1])
    assert rviz.kwargs['arguments'][0] == '-d' and config.name == 'agv.rviz' and config.is_file()
    assert not [n for n in nodes_from_launch_file() if n.kwargs.get('executable') == 'rviz2']


def test_the_rviz_configuration_shows_what_the_graph_publishes_as_it_publishes_it():
    """Each display's topic with the durability its publisher offers.

    The latched floor is transient local, where RViz's default is volatile: a volatile display
    would never see it. The QoS are the publishers' own (world/node.py, view/live.py).
    """
    from rclpy.qos import DurabilityPolicy

    from agv_nodes import qos

    config = yaml.safe_load((REPO / 'config' / 'agv.rviz').read_text())
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'map'  # world/markers' frame
    published = {'world/markers': qos.LATCHED, 'world/route': qos.LATCHED,
                 'world/obstacle_markers': qos.LATCHED,
                 'world/pose': qos.STREAM_WRITER, 'odom': qos.EVENTS,
                 'hw/camera/front': qos.STREAM_WRITER}
    shown = {d['Topic']['Value']: d['Topic'] for d in manager['Displays'] if 'Topic' in d}
    assert set(shown) == set(published)
    for topic, display in shown.items():
        latched = published[topic].durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert (display['Durability Policy'] == 'Transient Local') is latched, topic
