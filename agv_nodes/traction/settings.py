"""Traction settings: the classes its parameters.yaml declares the parameters of."""

from agv_nodes.settings import settings_class


@settings_class
class TractionParams:
    """The speed program (thesis App. B.2), its trips and the closed loop."""
