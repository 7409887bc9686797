"""Route following settings, declared in its parameters.yaml; nested groups give `wire.kp` etc."""

from agv_nodes.settings import settings_class


@settings_class
class WireParams:
    """Guide-wire steering (Baker 1983, 3.5.3, 6.2.1, 7.2; tuned in bench/route_bench.py)."""


@settings_class
class ImageParams:
    """Camera window calibration and noise filter (Rajagopalan 1991, 4.2, Table 6.1, App. F.2)."""


@settings_class
class SteeringParams:
    """Camera steering laws and the CONCIC-II geometry (Rajagopalan 1991, 5.2; Table 6.1)."""


@settings_class
class TurningParams:
    """Taking a branch at a road sign (App. F.6, which leaves the spin in place assumed here)."""


@settings_class
class RouteParams:
    """All route-following settings."""
