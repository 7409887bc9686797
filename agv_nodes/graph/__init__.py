"""The node graph and how it is launched: one process per node, as `ros2 launch` would start it.

`model` (config/graph.yaml), `parameters` (what the launch sets, for agv-launch and
launch/agv_demo.launch.py), `supervisor` (the running graph), `child` (each node's wrapper), `cli`
(agv-launch). Nothing is imported here: the launch file needs `model` and `parameters` only.
"""
