"""Which code runs the world's hottest loops: C (`_kernels.c`, built by setup.py) or Python.

The Electruk's substeps (`vehicles.py`, `Electruk.step`), the guide-wire pickup's field
(`guide_wire.py`, `GuideWirePickup.coils`) and the marker sensor's optics (`marker_sensor.py`,
`MarkerSensorModel._look`) are most of the world's arithmetic per sample. `_kernels.c` does the
same arithmetic as that Python code, in the same order, with the same functions (the C
library's, and Python's own `math.hypot`): the two give the same bits
(test/test_world_kernels.py), and the choice changes only speed. The world parameter
`kernels` chooses (agv_nodes/kernel_choice.py).
"""

from __future__ import annotations

from types import ModuleType

from agv_nodes import kernel_choice

try:
    # a C extension setup.py builds, with no stub: mypy reads no .so
    from agv_nodes.world import _kernels as compiled  # type: ignore[attr-defined]
except ImportError:  # not built (no C compiler at install): the Python code runs
    compiled = None

CHOICES = kernel_choice.CHOICES


def select(choice: str = 'auto') -> ModuleType | None:
    """Return the compiled kernels `choice` asks for, or None for the Python code."""
    return kernel_choice.select(compiled, choice, 'world')
