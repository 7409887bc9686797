"""The simulation channel: how far each node has got in sim time (ROS-free constants).

Each node publishes on `sim/progress/<node>` (rosgraph_msgs/Clock) the latest /clock it has
handled, at most once per PERIOD; the world (agv_nodes.world.pacing) waits while one lags. See
docs/architecture.md, "Time and pacing".
"""

PERIOD = 0.02  # s of sim time between a node's progress messages
LINK = 'progress'  # the progress writer's name in graph/links announcements and wait lists
# The world's /clock writer in wait lists ('world>clock:N'): N readers matched before it moves,
# so a recorder and the nodes on sim time have every /clock from the first.
CLOCK_LINK = 'clock'


def topic(node: str) -> str:
    """Return the relative topic a node's progress goes on."""
    return f'sim/progress/{node}'
