"""Communications settings: the classes its parameters.yaml declares the parameters of."""

from __future__ import annotations

from agv_nodes.settings import settings_class


@settings_class
class CommsParams:
    """The task queue and its relay to the executive."""
