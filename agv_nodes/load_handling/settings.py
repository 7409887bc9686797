"""Load handling settings: the classes its parameters.yaml declares the parameters of."""

from __future__ import annotations

from agv_nodes.settings import settings_class


@settings_class
class LoadParams:
    """The conveyor transfers (Baker 1983, 3.5.3, 6.3.2)."""
