"""The simulation channel: how far each node has got in sim time (ROS-free constants).

Pacing a faster-than-real-time world is the simulator's business, never the 16-byte records'.
With a simulated world (agv-launch world:=sim, sim time), each node publishes on its own topic
`sim/progress/<node>` a rosgraph_msgs/Clock: the latest /clock it has fully handled, timers
included, at most once per PERIOD of sim time. Under the EventsExecutor a node takes /clock in
arrival order with its other inputs, so a node that has handled /clock at t has handled every
sensor sample the world sent before it. The world (agv_nodes/world/pacing.py) waits while a
node's progress lags. With hardware instead of the world, none of this exists.
"""

from __future__ import annotations

PERIOD = 0.02  # s of sim time between a node's progress messages
LINK = 'progress'  # the progress writer's name in graph/links announcements and wait lists


def topic(node: str) -> str:
    """Return the relative topic a node's progress goes on."""
    return f'sim/progress/{node}'
