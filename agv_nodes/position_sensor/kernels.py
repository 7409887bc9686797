"""Which code runs the position sensor's arithmetic per snapshot: C (`_thresh.c`) or Python.

At 340 snapshots a second, SUBT, TOTAL and THRESH over the eight detectors
(`PositionSensorCore.sample`) and the sequence decoder's running sum
(`PositionSensorCore._sequence_levels`) are most of the sensor's work. `_thresh.c` does the
same arithmetic on the same Python lists, updating them as the Python code does, so the two
give the same CODE, decisions, state and levels, to the bit, and may take over from each other
at any snapshot (test/test_position_sensor_kernel.py holds them to that). The position sensor
parameter `kernels` chooses (agv_nodes/kernel_choice.py).
"""

from __future__ import annotations

from types import ModuleType

from agv_nodes import kernel_choice

try:
    # a C extension setup.py builds, with no stub: mypy reads no .so
    from agv_nodes.position_sensor import _thresh as compiled  # type: ignore[attr-defined]
except ImportError:  # not built (no C compiler at install): the Python code runs
    compiled = None

CHOICES = kernel_choice.CHOICES


def select(choice: str = 'auto') -> ModuleType | None:
    """Return the compiled kernel `choice` asks for, or None for the Python code."""
    return kernel_choice.select(compiled, choice, 'position sensor')
