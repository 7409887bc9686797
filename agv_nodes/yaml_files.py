"""Reading the package's YAML files (schemas, layouts, the graph): one mapping, checked keys."""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

import yaml


def read_mapping(path: Path, error: type[Exception],
                 keys: Collection[str] | None = None) -> dict[str, Any]:
    """Read the top-level mapping of a YAML file.

    Raise `error` (naming the file and the offending key) when the file cannot be read, is not
    a mapping, or has a key not in `keys`.
    """
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        reason = ' '.join(str(exc).split())  # one line, whatever the YAML parser printed
        raise error(f'{path}: cannot read: {reason}') from None
    if not isinstance(doc, dict):
        raise error(f'{path}: expected a mapping at the top level')
    extra = set(doc) - set(keys) if keys is not None else set()
    if extra:
        raise error(f'{path}: unknown key {sorted(extra)[0]!r}')
    return doc
