"""agv_nodes: a ROS 2 reproduction of the 1983 Cableform AGV (Baker 1983, Rajagopalan 1991)."""

__version__ = '0.1.0'
