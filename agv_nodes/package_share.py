"""Where the package's shared files (msg_schemas/, config/, launch/) live, and reading them.

Three installs must work: a colcon workspace or ROS install (ament_index: `share/agv_nodes` under
AMENT_PREFIX_PATH), a source checkout or `pip install -e` (next to the package), and a plain `pip
install` (setup.py's data_files in `<prefix>/share/agv_nodes`).
"""

from collections.abc import Collection
import functools
import os
from pathlib import Path
import sys
from typing import TYPE_CHECKING, Any

import yaml

PACKAGE = 'agv_nodes'
_MARKER = 'msg_schemas'


@functools.cache
def share_dir() -> Path:
    """Return the directory holding msg_schemas/, config/ and launch/ for this install."""
    if override := os.environ.get('AGV_NODES_SHARE'):
        return Path(override)
    # A source checkout / editable install first: the files next to this very module belong to
    # the code that is running, whatever else is on AMENT_PREFIX_PATH.
    candidates = [Path(__file__).resolve().parent.parent]
    try:
        from ament_index_python.packages import get_package_share_directory

        candidates.append(Path(get_package_share_directory(PACKAGE)))
    except Exception:  # noqa: BLE001 - ament_index absent or the package not registered
        pass
    candidates.append(Path(sys.prefix) / 'share' / PACKAGE)
    for candidate in candidates:
        if (candidate / _MARKER).is_dir():
            return candidate
    searched = ', '.join(str(c) for c in candidates)
    raise FileNotFoundError(f'{PACKAGE}: no {_MARKER}/ directory found (searched {searched})')


def schema_dir() -> Path:
    """Directory of the record schemas (one YAML file per 16-byte record)."""
    return share_dir() / 'msg_schemas'


def config_dir() -> Path:
    """Directory of the ROS-format parameter files and world layouts."""
    return share_dir() / 'config'


# libyaml's parser where PyYAML was built with it (the PyPI wheels are): the pure-Python one
# spent about half a second of every node's start-up on the record schemas and parameter files.
if TYPE_CHECKING:  # the checker takes the two for one: the same interface
    from yaml import SafeLoader as _SafeLoader
else:
    _SafeLoader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


class _UniqueKeyLoader(_SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping (it keeps the last)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f'key {key!r} given twice', key_node.start_mark)
            seen.add(key)
        return yaml.constructor.SafeConstructor.construct_mapping(self, node, deep)


def load_yaml(text: str) -> Any:
    """Parse YAML as yaml.safe_load does, but a key given twice in a mapping is an error."""
    return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass


def read_mapping(path: Path, error: type[Exception],
                 keys: Collection[str] | None = None) -> dict[str, Any]:
    """Read a YAML file's top-level mapping; `error` names the file and any key not in `keys`."""
    try:
        doc = load_yaml(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        reason = ' '.join(str(exc).split())  # one line, whatever the YAML parser printed
        raise error(f'{path}: cannot read: {reason}') from None
    if not isinstance(doc, dict):
        raise error(f'{path}: expected a mapping at the top level')
    if extra := set(doc) - set(keys) if keys is not None else set():
        raise error(f'{path}: unknown key {sorted(extra)[0]!r}')
    return doc
