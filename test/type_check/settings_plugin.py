"""A mypy plugin: the fields `agv_nodes.settings.settings_class` makes from parameters.yaml.

Every node's settings are declared once, as data, in the parameters.yaml beside its settings
module (agv_nodes/settings.py): the decorator turns the section named after a class into that
class's dataclass fields at import. A type checker reads the source, not the YAML, so without
this plugin every `params.steering.gain_theta` is an unknown attribute. The plugin reads the same
section and gives the class what the decorator gives it: one attribute per entry (bool, int,
float, str, a tuple of one of them, or a nested settings class), an `__init__` taking them as
optional arguments in order, and the dataclass signature `dataclasses.replace` checks against.
It reads the YAML with PyYAML's safe loader (the package's own loader adds only the duplicate-key
check, which the tests run).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from mypy.nodes import ARG_OPT, Argument, TypeInfo, Var
from mypy.plugin import ClassDefContext, Plugin
from mypy.plugins.common import add_attribute_to_class, add_method_to_class
from mypy.types import AnyType, Instance, NoneType, Type, TypeOfAny
import yaml

DECORATOR = 'agv_nodes.settings.settings_class'
DEFINITIONS = 'parameters.yaml'
SCALARS = {bool: 'builtins.bool', int: 'builtins.int', float: 'builtins.float',
           str: 'builtins.str'}
ARRAYS = {'bool_array': 'builtins.bool', 'integer_array': 'builtins.int',
          'double_array': 'builtins.float', 'string_array': 'builtins.str'}
REPLACE = '__mypy-replace'  # where mypy's dataclasses plugin looks for replace()'s signature

_sections: dict[Path, dict[str, Any]] = {}


def _section(path: Path, name: str) -> dict[str, Any] | None:
    if path not in _sections:
        doc = yaml.safe_load(path.read_text()) if path.is_file() else None
        _sections[path] = doc if isinstance(doc, dict) else {}
    section = _sections[path].get(name)
    return section if isinstance(section, dict) else None


def _entry_type(ctx: ClassDefContext, entry: Any) -> Type | None:
    """Return the type of one entry; None while a nested class is not analysed yet."""
    api = ctx.api
    if isinstance(entry, str):  # a nested group: a settings class of the same module
        node = api.lookup_fully_qualified_or_none(f'{ctx.cls.info.module_name}.{entry}')
        if node is None or not isinstance(node.node, TypeInfo):
            return None
        return Instance(node.node, [])
    if not isinstance(entry, dict) or 'default' not in entry:
        return AnyType(TypeOfAny.from_error)  # the decorator itself names the fault at import
    default = entry['default']
    if isinstance(default, list):
        item = ARRAYS.get(entry.get('type', ''))
        if item is None:
            return AnyType(TypeOfAny.from_error)
        return api.named_type('builtins.tuple', [api.named_type(item)])
    name = SCALARS.get(type(default))
    return api.named_type(name) if name else AnyType(TypeOfAny.from_error)


def _settings_class(ctx: ClassDefContext) -> bool:
    """Give the decorated class its fields; False asks mypy to come back (a nested class)."""
    info = ctx.cls.info
    module = ctx.api.modules.get(info.module_name)  # type: ignore[attr-defined]
    if module is None or not module.path:
        return True
    section = _section(Path(module.path).with_name(DEFINITIONS), info.name)
    if section is None:
        return True
    fields: list[tuple[str, Type]] = []
    for name, entry in section.items():
        typ = _entry_type(ctx, entry)
        if typ is None:
            if ctx.api.final_iteration:
                typ = AnyType(TypeOfAny.from_error)
            else:
                ctx.api.defer()
                return False
        fields.append((str(name), typ))
    for name, typ in fields:
        add_attribute_to_class(ctx.api, ctx.cls, name, typ, overwrite_existing=True)
    args = [Argument(Var(name, typ), typ, None, ARG_OPT) for name, typ in fields]
    add_method_to_class(ctx.api, ctx.cls, '__init__', args=args, return_type=NoneType())
    add_method_to_class(ctx.api, ctx.cls, REPLACE, args=args, return_type=NoneType(),
                        is_staticmethod=True)
    field_type = ctx.api.named_type('builtins.dict', [
        ctx.api.named_type('builtins.str'), AnyType(TypeOfAny.explicit)])
    add_attribute_to_class(ctx.api, ctx.cls, '__dataclass_fields__', field_type,
                           is_classvar=True, overwrite_existing=True)
    return True


class SettingsPlugin(Plugin):
    """See the module docstring."""

    def get_class_decorator_hook_2(
            self, fullname: str) -> Callable[[ClassDefContext], bool] | None:
        """Return the hook for classes decorated with `settings_class`."""
        return _settings_class if fullname == DECORATOR else None


def plugin(_version: str) -> type[Plugin]:
    """Return the plugin class (mypy's entry point)."""
    return SettingsPlugin
