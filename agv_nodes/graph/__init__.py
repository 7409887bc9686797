"""The node graph and how it is launched: one process per node, as `ros2 launch` would start it.

- `model`: the graph description (config/graph.yaml) and its nodes.
- `parameters`: what the launch sets for each node on top of the parameter file, the one source
  for both agv-launch and launch/agv_demo.launch.py.
- `supervisor`: the running graph (start, poll, stop, respawn) and its ROS domain.
- `child`: the wrapper each node process starts through (dies with its launcher).
- `cli`: agv-launch.

Nothing is imported here: the launch file needs `model` and `parameters` only.
"""
