"""ROS 2 launch file for a real Jazzy install: the same graph agv-launch starts.

    ros2 launch agv_nodes agv_demo.launch.py [namespace:=/agv2] [use_sim_time:=true]
        [time_factor:=1.0] [record_integrity:=e2e] [world:=sim|none] [bag:=/path/new_bag]
        [params_file:=<file>] [layout:=<name>] [respawn:=false] [realtime:=0]

Nodes, executables and roles come from share/agv_nodes/config/graph.yaml, and each node's
parameters from agv_nodes.graph.parameters.node_parameters - the same description and function
agv-launch uses, so the two cannot drift (test/test_launch_file.py checks it). The world writes
no ready file here (agv-launch's signal that time has started). With
world:=none the hardware topics must come from drivers (docs/hardware.md); record with
bag:=<dir> here, or with `ros2 bag record -s mcap -a` alongside.
"""

from pathlib import Path

from launch.actions import DeclareLaunchArgument, OpaqueFunction
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
}


def _nodes(context):
    from agv_nodes.graph.model import load_graph
    from agv_nodes.graph.parameters import (
        Options,
        check_realtime,
        node_parameters,
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
                      layout=arg['layout'] or None)
    check_realtime(options)
    graph = truck_graph(graph, options)
    params_file = arg['params_file'] or str(graph.parameters)
    nodes = []
    for spec in graph.nodes:
        if spec.role == 'world' and options.world == 'none':
            continue
        if spec.role == 'recorder' and options.bag is None:
            continue
        nodes.append(Node(package='agv_nodes', executable=spec.executable, name=spec.name,
                          namespace=options.namespace,
                          parameters=[params_file, node_parameters(graph, spec, options)],
                          output='screen', respawn=arg['respawn'] == 'true' and
                          spec.role == 'node',
                          prefix=(f'chrt -f {realtime_priority(spec, options)}'
                                  if realtime_priority(spec, options) else None)))
    return nodes


def generate_launch_description():
    """Return the launch description: arguments, then the nodes of config/graph.yaml."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=text)
         for name, (default, text) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_nodes)])
