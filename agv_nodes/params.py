"""Node parameters: declared from settings dataclasses (agv_nodes/settings.py), checked once.

Each field becomes a parameter with a descriptor (description, range, read-only if read at
start-up); a bad value, unknown name or unreadable file stops start-up with one line.
"""

from collections.abc import Sequence
import sys
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.node import Node

from agv_nodes.rclpy_internals import parameter_overrides
from agv_nodes.settings import (
    Parameter,
    ParameterFileError,
    SettingError,
    build,
    convert,
    node_level_names,
    parameter_file_values,
    parameters,
)


class ParameterError(ValueError):
    """A parameter value, name or file a node cannot start with (one line)."""


_ARRAYS = {bool: ParameterType.PARAMETER_BOOL_ARRAY, int: ParameterType.PARAMETER_INTEGER_ARRAY,
           float: ParameterType.PARAMETER_DOUBLE_ARRAY, str: ParameterType.PARAMETER_STRING_ARRAY}
_SCALARS = {bool: ParameterType.PARAMETER_BOOL, int: ParameterType.PARAMETER_INTEGER,
            float: ParameterType.PARAMETER_DOUBLE, str: ParameterType.PARAMETER_STRING}


def params_files(argv: Sequence[str] | None = None) -> list[str]:
    """Return the --params-file arguments of this process (for error messages)."""
    argv = list(sys.argv if argv is None else argv)
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == '--params-file']


def descriptor(p: Parameter) -> ParameterDescriptor:
    """Return the ROS parameter descriptor of one setting."""
    desc = ParameterDescriptor(name=p.name, description=p.spec.text(), read_only=p.spec.read_only)
    if p.kind is tuple and not p.default:
        # rclpy types an empty list as a byte array and then refuses any other list: an empty
        # default takes its type from what it is given (build() checks it)
        desc.dynamic_typing = True
    elif p.kind is tuple:
        desc.type = _ARRAYS[p.element]
    elif p.kind is float:
        desc.dynamic_typing = True  # `-p x:=2` gives an integer; build() takes it as 2.0
    else:
        desc.type = _SCALARS[p.kind]
    if p.spec.choices:
        desc.additional_constraints = f'one of {", ".join(p.spec.choices)}'
    if p.spec.lo is not None and p.spec.hi is not None and p.kind in (int, float):
        if p.kind is int:
            desc.integer_range = [IntegerRange(from_value=int(p.spec.lo),
                                               to_value=int(p.spec.hi), step=1)]
        else:
            desc.floating_point_range = [FloatingPointRange(from_value=float(p.spec.lo),
                                                            to_value=float(p.spec.hi))]
    return desc


def parameter_error(node: Node, name: str, value: Any, reason: str) -> ParameterError:
    """Return the one-line start-up error: node, parameter, value, reason and parameter files."""
    return ParameterError(f'{node.get_name()}: parameter {name!r} = {value!r}: {reason}{_where()}')


def _where() -> str:
    files = params_files()
    return f' (parameter files: {", ".join(files)})' if files else ''


def declare(node: Node, cls: type) -> Any:
    """Declare every setting of `cls` on `node` and build it from the values given."""
    values: dict[str, Any] = {}
    for p in parameters(cls):
        default: Any = list(p.default) if p.kind is tuple else p.default
        try:
            value = node.declare_parameter(p.name, default, descriptor(p)).value
        except (InvalidParameterTypeException, InvalidParameterValueException,
                ParameterUninitializedException) as exc:
            given = parameter_overrides(node).get(p.name, '?')
            try:  # rclpy's descriptor check came first: say it in our words when we can
                convert(p, given)
                reason = ' '.join(str(exc).split())
            except SettingError as ours:
                reason = ours.reason
            raise parameter_error(node, p.name, given, reason) from None
        if value is not None or p.kind is tuple:
            values[p.name] = value
    try:
        return build(cls, values)
    except SettingError as exc:
        raise ParameterError(f'{node.get_name()}: {exc}{_where()}') from None


def refuse_unknown(node: Node) -> None:
    """Stop start-up on a bad file or an unknown parameter (in this node's file section, or -p)."""
    declared = set(node.get_parameters_by_prefix(''))
    shared: set[str] = set()
    for path in params_files():
        try:
            common, own = parameter_file_values(path, node.get_name(),
                                                node.get_namespace().rstrip('/'))
        except ParameterFileError as exc:
            raise ParameterError(f'{node.get_name()}: {exc}') from None
        shared.update(common)
        for name, value in own.items():
            if name not in declared and not name.startswith('qos_overrides.'):
                raise ParameterError(f'{path}: node {node.get_name()}: unknown parameter '
                                     f'{name!r} (= {value!r})')
    for name, value in parameter_overrides(node).items():
        if name not in declared and name not in shared and name not in node_level_names() \
                and not name.startswith('qos_overrides.'):
            raise ParameterError(f'{node.get_name()}: unknown parameter {name!r} (= {value!r}) '
                                 f'given on the command line{_where()}')
