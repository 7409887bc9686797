"""Navigation settings: the classes its parameters.yaml declares the parameters of."""

from agv_nodes.settings import settings_class


@settings_class
class NavigationParams:
    """PC6/1's navigating and positioning loops (thesis App. B.1) and the controlled stop."""
