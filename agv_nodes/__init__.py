"""agv_nodes: a ROS 2 reproduction of the 1983 Cableform AGV (Baker 1983, Rajagopalan 1991)."""

import os

__version__ = '0.1.0'

# The process that started this one, read before any module of the package imports rclpy and
# the rest (seconds on a busy machine): a node whose starter dies meanwhile sees its parent
# change by the time it asks to die with it (agv_nodes.node_process.die_with_parent).
PARENT_AT_START = os.getppid()
