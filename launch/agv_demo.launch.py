"""ROS 2 launch file for a real Jazzy install: the same graph agv-launch starts.

    ros2 launch agv_nodes agv_demo.launch.py [namespace:=/agv2] [use_sim_time:=true]
        [time_factor:=1.0] [record_integrity:=e2e] [world:=sim|none] [bag:=/path/new_bag]
        [params_file:=<file>] [layout:=<name>] [respawn:=false] [realtime:=0]
        [vda5050:=false] [mqtt_url:=mqtt://host:port] [serial_number:=<name>]
        [trucks:=0] [set_down:=W2.2,W0.1] [external_master:=false] [foxglove:=8765]
        [rviz:=false]

Nodes, executables and roles come from share/agv_nodes/config/graph.yaml, and each node's
parameters from agv_nodes.graph.parameters.node_parameters - the same description and function
agv-launch uses, so the two cannot drift (test/test_launch_file.py checks it). The world writes
no ready file here (agv-launch's signal that time has started). With
world:=none the hardware topics must come from drivers (docs/hardware.md); record with
bag:=<dir> here, or with `ros2 bag record -s mcap -a` alongside. With vda5050:=true the
truck's VDA 5050 bridge starts too, on the broker of mqtt_url, else of AGV_MQTT_URL, else on a
broker (`python3 -m agv_nodes.mqtt.broker`) this launch starts on port 1883; the bridge keeps
trying until that broker listens. With trucks:=N it starts a fleet as `agv-launch --trucks N`
does (agv_nodes.graph.parameters.launch_units): each truck's nodes in /agvK, one world for the
floor, whose per-truck parameters go in a file this launch writes (its nodes are made by the
world process, so a dict for the launched node would not reach them).
"""

from pathlib import Path

from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription

ARGUMENTS = {
    'namespace': ('', 'namespace of this truck, e.g. /agv2'),
    'use_sim_time': ('true', "run the graph on the world's /clock"),
    'time_factor': ('1.0', 'simulated seconds per real second (0 = as fast as possible)'),
    'record_integrity': ('e2e', 'end-to-end protection of the records: e2e or none'),
    'world': ('sim', 'sim: the simulated world; none: hardware drivers publish hw/*'),
    'bag': ('', 'record every topic into this new bag directory (empty: no recorder)'),
    'params_file': ('', 'ROS parameter file (default: config/agv_demo.yaml)'),
    'layout': ('', "world layout (default: the parameter file's); its vehicle picks the truck"),
    'respawn': ('false', 'restart nodes that die'),
    'realtime': ('0', 'SCHED_FIFO priority 1-99 of the sensor-to-traction chain (0 = off)'),
    'vda5050': ('false', 'also start the VDA 5050 bridge: a master control drives the truck'),
    'mqtt_url': ('', "the bridge's MQTT broker (empty: AGV_MQTT_URL, else one started here)"),
    'serial_number': ('', "the truck's VDA 5050 serialNumber (empty: the namespace, or agv1)"),
    'trucks': ('0', 'a fleet: N trucks on one floor in namespaces /agv1../agvN (0: one truck)'),
    'set_down': ('', "a fleet's stop markers, one per truck, comma-separated (empty: parking)"),
    'external_master': ('false', "a fleet's bridges wait for a master of your own"),
    'foxglove': ('', 'also start live_view: a Foxglove WebSocket on this port (empty: none)'),
    'rviz': ('false', 'also start rviz2 with config/agv.rviz (rviz2 must be installed)'),
}
BROKER_PORT = 1883  # MQTT's own port: where a master control looks first


def _nodes(context):
    from dataclasses import replace
    import tempfile

    from agv_nodes.graph.model import load_graph
    from agv_nodes.graph.parameters import (
        Options,
        check_fleet,
        check_realtime,
        check_vda5050,
        floor_parameters,
        launch_units,
        node_parameters,
        parameter_file_text,
        realtime_priority,
        truck_graph,
    )
    from agv_nodes.package_share import config_dir  # ament_index share/agv_nodes when installed

    graph = load_graph(config_dir() / 'graph.yaml')
    arg = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    options = Options(namespace=arg['namespace'], use_sim_time=arg['use_sim_time'] == 'true',
                      time_factor=float(arg['time_factor']),
                      record_integrity=arg['record_integrity'], world=arg['world'],
                      bag=Path(arg['bag']) if arg['bag'] else None,
                      realtime=int(arg['realtime']),
                      params=Path(arg['params_file']) if arg['params_file'] else None,
                      layout=arg['layout'] or None, vda5050=arg['vda5050'] == 'true',
                      mqtt_url=arg['mqtt_url'] or None, serial_number=arg['serial_number'],
                      trucks=int(arg['trucks']),
                      set_down=[m for m in arg['set_down'].split(',') if m],
                      external_master=arg['external_master'] == 'true',
                      foxglove=int(arg['foxglove']) if arg['foxglove'] else None)
    check_realtime(options)
    graph = truck_graph(graph, options)
    check_vda5050(graph, options)
    check_fleet(graph, options)
    params_file = arg['params_file'] or str(graph.parameters)
    actions = []  # the broker, when this launch runs one, then the nodes
    if options.vda5050:
        from agv_nodes.mqtt.broker import broker_url  # the rule agv-launch follows

        options.mqtt_url = broker_url(options.mqtt_url)
        if options.mqtt_url is None:
            options.mqtt_url = f'mqtt://127.0.0.1:{BROKER_PORT}'
            actions.append(ExecuteProcess(cmd=['python3', '-m', 'agv_nodes.mqtt.broker', '--port',
                                               str(BROKER_PORT)], name='mqtt_broker',
                                          output='screen'))
    for _label, spec, namespace in launch_units(graph, options):
        own = replace(options, namespace=namespace)
        if options.trucks and spec.role == 'world':  # the floor's file: its nodes and theirs
            with tempfile.NamedTemporaryFile('w', prefix='agv_floor_', suffix='.yaml',
                                             delete=False) as floor:
                floor.write(parameter_file_text(floor_parameters(graph, spec, own)))
            params = floor.name
        else:
            params = node_parameters(graph, spec, own)
        actions.append(Node(package='agv_nodes', executable=spec.executable, name=spec.name,
                          namespace=namespace, parameters=[params_file, params],
                          output='screen', respawn=arg['respawn'] == 'true' and
                          spec.role == 'node',
                          prefix=(f'chrt -f {realtime_priority(spec, options)}'
                                  if realtime_priority(spec, options) else None)))
    if arg['rviz'] == 'true':  # relative topics: in the (first) truck's namespace
        actions.append(Node(package='rviz2', executable='rviz2', name='rviz2',
                            namespace=options.namespace or ('/agv1' if options.trucks else ''),
                            arguments=['-d', str(config_dir() / 'agv.rviz')], output='screen'))
    return actions


def generate_launch_description():
    """Return the launch description: arguments, then the nodes of config/graph.yaml."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=text)
         for name, (default, text) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_nodes)])
