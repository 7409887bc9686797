"""Track-geometry settings, declared in the parameters.yaml beside this module."""

from agv_nodes.settings import settings_class


@settings_class
class IdentificationParams:
    """Odometry and the least-squares track fits (Rajagopalan 1991, 5.4.1-5.4.2)."""


@settings_class
class FeedForwardParams:
    """Gains and options of the feed-forward law (Rajagopalan 1991, 5.4.5-5.4.6).

    The law and how its gains were chosen: feed_forward.py.
    """
