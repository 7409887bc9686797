"""Position sensor settings: the classes its parameters.yaml declares the parameters of."""

from typing import Any

from agv_nodes.markers import THRESHOLDS
from agv_nodes.position_sensor import kernels
from agv_nodes.settings import settings_class


@settings_class
class SensorProcessing:
    """PC6/1's SAMPLE, THRESH and DECODE (thesis ch 5, App. B.1) and the modern decoders."""

    def thresholds(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """(white, black) per detector: the settings, or Table 7.1 of `unit` where empty."""
        table = THRESHOLDS.get(self.unit, THRESHOLDS['sensor1'])
        return tuple(self.white) or table['white'], tuple(self.black) or table['black']

    def problems(self) -> list[tuple[str, Any, str]]:
        """Check what `build` cannot field by field.

        Each black threshold below its white, and `kernels: c` only where the kernel was built
        (no C compiler at install leaves it out).
        """
        out = []
        try:
            kernels.select(self.kernels)
        except ValueError as exc:
            out.append(('kernels', self.kernels, str(exc)))
        white, black = self.thresholds()
        low = [d for d, (w, b) in enumerate(zip(white, black, strict=True), 1) if b >= w]
        if not low:
            return out
        name = 'black' if self.black or not self.white else 'white'
        return [*out, (name, list(getattr(self, name)), 'each black threshold must be below its '
                       f'white one (detector {", ".join(map(str, low))}; empty = Table 7.1 of '
                       f'{self.unit})')]
