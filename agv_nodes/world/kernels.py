"""Which code runs the world's hottest loops: C (`_kernels.c`, built by setup.py) or Python.

The Electruk's substeps (`vehicles.py`, `Electruk.step`), the guide-wire pickup's field
(`guide_wire.py`, `GuideWirePickup.coils`) and the marker sensor's optics (`marker_sensor.py`,
`MarkerSensorModel._look`) are most of the world's arithmetic per sample. `_kernels.c` does the
same arithmetic as that Python code, in the same order, with the same functions (the C
library's, and Python's own `math.hypot`): the two give the same bits
(test/test_world_kernels.py), and the choice changes only speed. The world parameter
`kernels` chooses: `auto` (default) the C code where it is built, else Python; `c` insists on
it; `python` never uses it. The extension is optional: a machine without a C compiler
installs the package without it and runs the Python code.
"""

from __future__ import annotations

from types import ModuleType

try:
    from agv_nodes.world import _kernels as compiled
except ImportError:  # not built (no C compiler at install): the Python code runs
    compiled = None

CHOICES = ('auto', 'c', 'python')


def select(choice: str = 'auto') -> ModuleType | None:
    """Return the compiled kernels `choice` asks for, or None for the Python code."""
    if choice not in CHOICES:
        raise ValueError(f'world kernels: {choice!r} is not one of {", ".join(CHOICES)}')
    if choice == 'python':
        return None
    if choice == 'c' and compiled is None:
        raise ValueError("world kernels: 'c' asks for the compiled kernels, which are not built "
                         '(pip install -e . builds them with the C compiler)')
    return compiled
