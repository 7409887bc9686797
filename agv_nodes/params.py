"""Node parameters: declared with descriptors, checked once at start-up.

A bad value stops start-up with one message naming the node, the parameter file(s) given with
--params-file, the key and the value (rclpy itself rejects unparsable YAML and wrong types).
"""

from __future__ import annotations

from collections.abc import Sequence
import sys
from typing import Any

from rcl_interfaces.msg import IntegerRange, ParameterDescriptor
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.node import Node


class ParameterError(ValueError):
    """A parameter value a node cannot run with."""


def params_files(argv: Sequence[str] | None = None) -> list[str]:
    """The --params-file arguments of this process (for error messages)."""
    argv = list(sys.argv if argv is None else argv)
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == '--params-file']


class Parameters:
    """Declares a node's parameters and reads them back, validated."""

    def __init__(self, node: Node) -> None:
        self.node = node

    def _fail(self, name: str, value: Any, reason: str) -> None:
        files = params_files()
        where = f' (parameter files: {", ".join(files)})' if files else ''
        raise ParameterError(f'{self.node.get_name()}: parameter {name!r} = {value!r}: '
                             f'{reason}{where}')

    def _declare(self, name: str, default: Any, desc: ParameterDescriptor) -> Any:
        try:
            return self.node.declare_parameter(name, default, desc).value
        except (InvalidParameterTypeException, InvalidParameterValueException,
                ParameterUninitializedException) as exc:
            override = self.node._parameter_overrides.get(name)  # what the user asked for
            value = override.value if override is not None else '?'
            self._fail(name, value, ' '.join(str(exc).split()))

    def number(self, name: str, default: float, description: str,
               lo: float | None = None, hi: float | None = None) -> float:
        """A float parameter within [lo, hi] (integers are accepted: `-p x:=2`)."""
        desc = ParameterDescriptor(description=description, dynamic_typing=True)
        if lo is not None and hi is not None:
            desc.description += f' [{lo}, {hi}]'
        value = self._declare(name, float(default), desc)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self._fail(name, value, 'must be a number')
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            self._fail(name, value, f'outside {lo}..{hi}')
        return float(value)

    def integer(self, name: str, default: int, description: str,
                lo: int | None = None, hi: int | None = None) -> int:
        """An integer parameter within [lo, hi]."""
        desc = ParameterDescriptor(description=description)
        if lo is not None and hi is not None:
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        value = self._declare(name, int(default), desc)
        if isinstance(value, bool) or not isinstance(value, int):
            self._fail(name, value, 'must be an integer')
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            self._fail(name, value, f'outside {lo}..{hi}')
        return int(value)

    def choice(self, name: str, default: str, description: str,
               choices: Sequence[str]) -> str:
        """A string parameter from a fixed set."""
        desc = ParameterDescriptor(description=f'{description} (one of {", ".join(choices)})')
        value = self._declare(name, default, desc)
        if value not in choices:
            self._fail(name, value, f'not one of {list(choices)}')
        return str(value)

    def text(self, name: str, default: str, description: str) -> str:
        """A free string parameter."""
        desc = ParameterDescriptor(description=description)
        value = self._declare(name, default, desc)
        if not isinstance(value, str):
            self._fail(name, value, 'must be a string')
        return value

    def flag(self, name: str, default: bool, description: str) -> bool:
        """A boolean parameter."""
        desc = ParameterDescriptor(description=description)
        value = self._declare(name, bool(default), desc)
        if not isinstance(value, bool):
            self._fail(name, value, 'must be true or false')
        return value

    def numbers(self, name: str, default: Sequence[float], description: str,
                length: int | None = None) -> list[float]:
        """A list of floats (an empty list means "derive it")."""
        desc = ParameterDescriptor(description=description)
        value = self._declare(name, [float(v) for v in default] or [0.0], desc)
        value = list(value)
        if not default and value == [0.0]:
            return []
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            self._fail(name, value, 'must be a list of numbers')
        if length is not None and len(value) != length:
            self._fail(name, value, f'needs exactly {length} values')
        return [float(v) for v in value]

    def texts(self, name: str, default: Sequence[str], description: str) -> list[str]:
        """A list of strings."""
        desc = ParameterDescriptor(description=description)
        value = self._declare(name, list(default) or [''], desc)
        return [v for v in value or () if v]  # a file's `[]` has no type: rclpy gives None

    def fail(self, name: str, value: Any, reason: str) -> None:
        """Refuse a value the node found unusable after reading it."""
        self._fail(name, value, reason)
