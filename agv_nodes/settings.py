"""Settings: every parameter of a node declared once, in the parameters.yaml of its package.

ROS-free. Each entry of a parameters.yaml carries a parameter's default, what it means and its
constraints (range, choices, list length, whether it may change at run time); `settings_class`
turns the section named after a class into that class's dataclass fields. Nodes declare one ROS
parameter per field (agv_nodes/params.py); the lock-step harness reads the same parameter file
with `settings_from_file`; both build the dataclass through `build`, the one place values are
checked. A nested settings dataclass gives dotted names (`wire.kp`), as ROS 2 does for nested
mappings in a parameter file. A class may add a `problems()` method for checks that span
fields; it returns (name, value, reason) triples. Keeping the declarations as data follows
ROS 2's generate_parameter_library, whose YAML files hold the same facts.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import MISSING, Field, dataclass, field, fields, is_dataclass
import functools
from pathlib import Path
import re
import sys
import types
import typing
from typing import Any

import yaml

from agv_nodes.package_share import load_yaml

SPEC = 'agv_nodes.setting'
SCALARS = (bool, int, float, str)


@dataclass(frozen=True)
class Spec:
    """What a setting means and what values it takes."""

    description: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    length: int | None = None  # a list: exactly this many items (or none: "derive it")
    read_only: bool = True  # False: may be set while the node runs

    def text(self) -> str:
        """Return the description with its constraints, as the parameter descriptor shows it."""
        words = [self.description]
        if self.choices:
            words.append(f'(one of {", ".join(self.choices)})')
        if self.lo is not None or self.hi is not None:
            words.append(f'[{self.lo}, {self.hi}]')
        return ' '.join(words)


DEFINITIONS = 'parameters.yaml'
_ARRAY_TYPES = {'bool_array': bool, 'integer_array': int, 'double_array': float,
                'string_array': str}
_ENTRY_KEYS = frozenset({'default', 'type', 'description', 'range', 'choices', 'length',
                         'read_only'})


class DefinitionError(ValueError):
    """A parameters.yaml entry that cannot declare a setting (names the file, class and key)."""


@functools.cache
def _definitions(path: Path) -> dict[str, Any]:
    doc = load_yaml(path.read_text())
    if not isinstance(doc, dict):
        raise DefinitionError(f'{path}: expected settings classes at the top level')
    return doc


def _declaration(where: str, entry: Any) -> tuple[Any, Any, Spec]:
    """(type hint, default, spec) of one parameters.yaml entry."""
    if not isinstance(entry, dict) or 'default' not in entry or 'description' not in entry:
        raise DefinitionError(f'{where}: needs a mapping with default and description')
    unknown = set(entry) - _ENTRY_KEYS
    if unknown:
        raise DefinitionError(f'{where}: unknown key {sorted(unknown)[0]!r}')
    default = entry['default']
    if isinstance(default, list):
        item = _ARRAY_TYPES.get(entry.get('type', ''))
        if item is None or not all(type(v) is item for v in default):
            raise DefinitionError(f'{where}: a list default needs a type, one of '
                                  f'{", ".join(_ARRAY_TYPES)}, that its items have')
        hint: Any = types.GenericAlias(tuple, (item, ...))  # tuple[item, ...]
        default = tuple(default)
    elif type(default) in SCALARS and 'type' not in entry:
        hint = type(default)
    else:
        raise DefinitionError(f'{where}: default {default!r} is not a bool, int, float or '
                              'string (a list needs a type)')
    lo, hi = entry.get('range', (None, None))
    spec = Spec(' '.join(str(entry['description']).split()), lo, hi,
                tuple(entry.get('choices', ())), entry.get('length'),
                entry.get('read_only', True))
    return hint, default, spec


def settings_class(cls: type) -> type:
    """Make `cls` a settings dataclass with one field per entry of its parameters.yaml section.

    The section is the one named after the class in the parameters.yaml beside the class's
    module. An entry whose value is a class name is a nested group: a field holding that
    settings class (defined earlier in the same module), its parameters named `group.name`.
    """
    path = Path(sys.modules[cls.__module__].__file__ or '').with_name(DEFINITIONS)
    section = _definitions(path).get(cls.__name__)
    if not isinstance(section, dict):
        raise DefinitionError(f'{path}: no section {cls.__name__}')
    module = sys.modules[cls.__module__]
    annotations: dict[str, Any] = {}
    for name, entry in section.items():
        where = f'{path}: {cls.__name__}.{name}'
        if isinstance(entry, str):  # a nested group: the settings class of that name
            group = getattr(module, entry, None)
            if not (isinstance(group, type) and is_dataclass(group)):
                raise DefinitionError(f'{where}: {entry!r} is no settings class of '
                                      f'{cls.__module__}')
            annotations[name] = group
            setattr(cls, name, field(default_factory=group))
            continue
        annotations[name], default, spec = _declaration(where, entry)
        setattr(cls, name, field(default=default, metadata={SPEC: spec}))
    cls.__annotations__ = annotations
    return dataclass(cls)


@dataclass(frozen=True)
class Parameter:
    """One setting as a parameter: dotted name, type, default, spec."""

    name: str
    kind: type  # bool, int, float, str or tuple
    item: type | None  # the element type of a tuple
    default: Any
    spec: Spec

    @property
    def element(self) -> type:
        """Return the element type of a list setting."""
        if self.item is None:
            raise TypeError(f'settings: {self.name} is no list')
        return self.item


class SettingError(ValueError):
    """A value a setting cannot take; names the parameter, the value and why."""

    def __init__(self, name: str, value: Any, reason: str) -> None:
        self.name, self.value, self.reason = name, value, reason
        super().__init__(f'parameter {name!r} = {value!r}: {reason}')


def _kind(hint: Any) -> tuple[type, type | None]:
    if typing.get_origin(hint) is tuple:
        return tuple, typing.get_args(hint)[0]
    if hint in SCALARS:
        return hint, None
    raise TypeError(f'settings: unsupported type {hint!r}')


@functools.cache
def parameters(cls: type, prefix: str = '') -> tuple[Parameter, ...]:
    """Every setting of `cls` and of its nested settings dataclasses, in declaration order."""
    hints = typing.get_type_hints(cls)
    out: list[Parameter] = []
    for f in fields(cls):
        hint = hints[f.name]
        if SPEC in f.metadata:
            kind, item = _kind(hint)
            out.append(Parameter(prefix + f.name, kind, item, _default(f), f.metadata[SPEC]))
        elif isinstance(hint, type) and is_dataclass(hint):
            out.extend(parameters(hint, f'{prefix}{f.name}.'))
    return tuple(out)


def _default(f: Field) -> Any:
    if f.default is not MISSING:
        return f.default
    if not callable(f.default_factory):  # every settings field has one or the other
        raise DefinitionError(f'{f.name}: a settings field without a default')
    return f.default_factory()


def _scalar(p: Parameter, kind: type, value: Any) -> Any:
    if kind is bool:
        if not isinstance(value, bool):
            raise SettingError(p.name, value, 'must be true or false')
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float) if kind is float else kind):
        raise SettingError(p.name, value, {int: 'must be an integer', float: 'must be a number',
                                           str: 'must be a string'}[kind])
    if kind is float and isinstance(value, (int, float)):  # it is (checked above)
        value = float(value)
    if p.spec.choices and value not in p.spec.choices:
        raise SettingError(p.name, value, f'not one of {list(p.spec.choices)}')
    if (p.spec.lo is not None and value < p.spec.lo) or \
            (p.spec.hi is not None and value > p.spec.hi):
        raise SettingError(p.name, value, f'outside {p.spec.lo}..{p.spec.hi}')
    return value


def convert(p: Parameter, value: Any) -> Any:
    """`value` as the setting holds it (a list as a tuple); SettingError when it cannot be."""
    if p.kind is not tuple:
        return _scalar(p, p.kind, value)
    if value is None:  # an empty list in a parameter file has no type: ROS gives None
        return ()
    if not isinstance(value, (list, tuple)):
        raise SettingError(p.name, value, 'must be a list')
    items = tuple(_scalar(p, p.element, v) for v in value)
    if p.spec.length is not None and items and len(items) != p.spec.length:
        raise SettingError(p.name, list(value), f'needs exactly {p.spec.length} values')
    return items


def build(cls: type, values: Mapping[str, Any]) -> Any:
    """Build an instance of the settings dataclass `cls` from parameter values by dotted name.

    Missing ones take their defaults; SettingError for an unknown name or a bad value.
    """
    known = {p.name: p for p in parameters(cls)}
    for name in values:
        if name not in known:
            raise SettingError(name, values[name], 'no such parameter')
    converted = {name: convert(known[name], value) for name, value in values.items()}
    obj = _assemble(cls, converted, '')
    for name, value, reason in getattr(obj, 'problems', lambda: [])():
        raise SettingError(name, value, reason)
    return obj


def _assemble(cls: type, values: Mapping[str, Any], prefix: str) -> Any:
    hints = typing.get_type_hints(cls)
    kwargs = {}
    for f in fields(cls):
        if not f.init:
            continue
        name, hint = prefix + f.name, hints[f.name]
        if SPEC in f.metadata:
            if name in values:
                kwargs[f.name] = values[name]
        elif isinstance(hint, type) and is_dataclass(hint):
            kwargs[f.name] = _assemble(hint, values, name + '.')
    return cls(**kwargs)


def values_of(obj: Any) -> dict[str, Any]:
    """Return the parameter values an instance holds, by dotted name (lists as lists)."""
    out = {}
    cls: type = type(obj)
    for p in parameters(cls):
        value: Any = obj
        for part in p.name.split('.'):
            value = getattr(value, part)
        out[p.name] = list(value) if isinstance(value, tuple) else value
    return out


# -- ROS 2 parameter files ---------------------------------------------------------------------
def _pattern(key: str) -> re.Pattern[str]:
    """Turn a parameter file's node key into a regular expression over a node's full name.

    Keys such as `/**`, `/**/traction`, `traction`, `/agv2/traction`; full names such as
    `/traction`, `/agv2/traction`.
    """
    parts = []
    for token in str(key).strip('/').split('/'):
        parts.append({'**': '(?:/[^/]+)*', '*': '/[^/]+'}.get(token, '/' + re.escape(token)))
    return re.compile(''.join(parts) + '$')


def flatten(mapping: Mapping[str, Any], prefix: str = '') -> Iterator[tuple[str, Any]]:
    """Nested parameter mappings as dotted names (what ROS 2 makes of them)."""
    for key, value in mapping.items():
        if isinstance(value, dict):
            yield from flatten(value, f'{prefix}{key}.')
        else:
            yield prefix + str(key), value


class ParameterFileError(ValueError):
    """A parameter file that cannot be read, or a key no parameter of its node has."""


def read_parameter_file(path: Path | str) -> dict[str, Any]:
    """Read a ROS 2 parameter file's top-level mapping.

    ParameterFileError names the file (and the line, when YAML says which) if it cannot be
    read.
    """
    path = Path(path)
    try:
        doc = load_yaml(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None)
        line = f' line {mark.line + 1}' if mark is not None else ''
        reason = ' '.join(str(getattr(exc, 'problem', '') or exc).split())
        raise ParameterFileError(f'{path}:{line}: not YAML: {reason}') from None
    except OSError as exc:
        raise ParameterFileError(f'{path}: cannot read: {exc.strerror}') from None
    if not isinstance(doc, dict):
        raise ParameterFileError(f'{path}: expected node names at the top level')
    for key, section in doc.items():
        if not isinstance(section, dict) or not isinstance(section.get('ros__parameters'),
                                                              dict):
            raise ParameterFileError(f'{path}: key {key!r}: needs a ros__parameters mapping')
    return doc


def parameter_file_values(path: Path | str, node: str,
                          namespace: str = '') -> tuple[dict[str, Any], dict[str, Any]]:
    """(shared, own): the values a parameter file gives one node, by dotted name.

    `shared` comes from sections whose last part is a wildcard (`/**`: every node; a node
    ignores the names it has no parameter for), `own` from sections that name the node
    (`/**/traction`), where a name the node does not have is an error. Later sections win,
    as in ROS 2.
    """
    full = f'{namespace.rstrip("/")}/{node}' if namespace else f'/{node}'
    shared: dict[str, Any] = {}
    own: dict[str, Any] = {}
    for key, section in read_parameter_file(path).items():
        if not _pattern(key).match(full):
            continue
        target = shared if str(key).rstrip('/').split('/')[-1] in ('*', '**') else own
        target.update(flatten(section['ros__parameters']))
    return shared, own


def settings_from_file(cls: type, path: Path | str, node: str,
                       overrides: Mapping[str, Any] | None = None,
                       also_known: frozenset[str] = frozenset()) -> Any:
    """Build `cls` as the node `node` gets it from a parameter file plus `overrides`.

    `overrides` are by dotted name, as `-p NAME:=VALUE` would give them: this is what the lock-step
    harness runs with. ParameterFileError names the file, node and key of a name the node does not
    have (`also_known`: the node's parameters besides `cls` and every node's own).
    """
    known = {p.name for p in parameters(cls)}
    shared, own = parameter_file_values(path, node)
    for name, value in own.items():
        if name not in known and name not in also_known and name not in node_level_names():
            raise ParameterFileError(f'{path}: node {node}: unknown parameter {name!r} '
                                     f'(= {value!r})')
    values = {k: v for k, v in {**shared, **own}.items() if k in known}
    values.update(overrides or {})
    try:
        return build(cls, values)
    except SettingError as exc:
        raise ParameterFileError(f'{path}: node {node}: {exc}') from None


# The stop switches (std_msgs/Bool, true = stop) and their writers by default, as msg_schemas/
# names each record's: the radio receiver's driver (in the tests, the probe's node of that name,
# test/graph_probe.py) and the world's bumper. record_writers names another, as for a record.
SWITCH_WRITERS = {'radio_stop': 'radio_receiver', 'bumper': 'world'}
# The cameras' frames (route following steers the CONCIC-II by them), from the world's cameras.
FRAME_WRITERS = {'camera_front': 'world', 'camera_rear': 'world'}
_GID_HEX = re.compile(r'gid:(?:[0-9a-fA-F]{2}){1,16}')


@settings_class
class ProcessSettings:
    """What every node process of the package has (agv_nodes/node_process.py)."""

    def writer_nodes(self) -> dict[str, str]:
        """Return the record_writers entries: record or switch -> the writer to take it from.

        A writer is a node name or `gid:<hex>` (an endpoint's GID, or its first bytes).
        """
        return dict(entry.split('=', 1) for entry in self.record_writers)  # type: ignore[attr-defined]

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks `build` needs beyond each field's own: record_writers' entries."""
        from agv_nodes.records import codec  # the schemas, only when a node is built

        names = {s.name for s in codec()} | set(SWITCH_WRITERS) | set(FRAME_WRITERS)
        for entry in self.record_writers:  # type: ignore[attr-defined]
            record, sep, node = entry.partition('=')
            gid = node.startswith('gid:')
            if not sep or record not in names or not node.strip('/') or ' ' in node \
                    or (gid and not _GID_HEX.fullmatch(node)):
                return [('record_writers', list(self.record_writers),  # type: ignore[attr-defined]
                         f'entry {entry!r} is not record=node or record=gid:<hex, up to 16 '
                         'bytes> with a record of msg_schemas/ or another input '
                         f'({", ".join([*SWITCH_WRITERS, *FRAME_WRITERS])})')]
        return []


@settings_class
class NodeSettings(ProcessSettings):
    """What every sub-system node has besides its core's settings (agv_nodes/core_node.py)."""


# Parameters rclpy itself declares on every node.
RCLPY_PARAMETERS = frozenset({'use_sim_time', 'start_type_description_service'})


def node_level_names() -> frozenset[str]:
    """Names any node may be given besides its core's settings."""
    return RCLPY_PARAMETERS | {p.name for p in parameters(NodeSettings)}
