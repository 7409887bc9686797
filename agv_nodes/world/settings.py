"""World settings: WorldParams, the simulated hardware, and WorldNodeSettings, the node's own."""

from agv_nodes.settings import ProcessSettings, settings_class


@settings_class
class ElectrukParams:
    """The A.W.D. Electruk tug (Baker 1983); [A]: 80 % duty ~1 m/s unloaded, 20 % ~0.2, <5 % 0."""


@settings_class
class Concic2Params:
    """CONCIC-II (Rajagopalan 1991, 6.3.1-6.3.2, 6.3.11, Table 6.1, App. B.3-B.5, App. C)."""


@settings_class
class SensorParams:
    """Optics and electronics of the Mk 1 marker sensor ([A] unless noted)."""


@settings_class
class PickupParams:
    """Guide-wire coil geometry and scaling ([A])."""

    @property
    def nominal(self) -> float:
        """Counts of each coil with the sensor point right over a long straight wire."""
        h, y = self.coil_height, self.coil_spacing / 2.0
        return self.gain * 2.0 * h / (h * h + y * y)


@settings_class
class CameraParams:
    """Binary camera window and noise (Rajagopalan 1991, Tables 6.1 and 6.3)."""


@settings_class
class SonarParams:
    """The CONCIC-II's front ultrasonic sensor (Rajagopalan 1991, 6.3.11; sonar.py)."""


@settings_class
class WorldParams:
    """The simulated hardware: rates, the trip relay, conveyors, and each device's model."""


@settings_class
class WorldNodeSettings(ProcessSettings):
    """The world node's own parameters: layout, /clock, waiting for the graph, pacing on it."""
