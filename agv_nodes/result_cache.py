"""Results of slow pure computations, kept on disk by their inputs and this package's code.

The layout check (agv_nodes.world.layout_check) drives every route of a layout, seconds of CPU,
and the marker sensor's threshold experiment (agv_nodes.world.marker_sensor) a third of a
second; the world node and the lock-step harness run both each time they start. Their results
depend only on their inputs and the code, so each is computed once per machine: the key is a
digest of the inputs' text and of every source file of the package, so any change to either
computes it afresh. Entries are JSON files under `$AGV_NODES_CACHE` (default
`$XDG_CACHE_HOME/agv_nodes`, else `~/.cache/agv_nodes`); set `AGV_NODES_CACHE=off` to compute
every time. A cache that cannot be read or written is skipped, never an error.
"""

from collections.abc import Callable
import functools
import hashlib
import json
import os
from pathlib import Path
import tempfile
from typing import Any

CACHE_ENV = 'AGV_NODES_CACHE'
PACKAGE = Path(__file__).resolve().parent
_memory: dict[str, Any] = {}


def cache_dir() -> Path | None:
    """Return where entries live (None: caching is off)."""
    chosen = os.environ.get(CACHE_ENV, '')
    if chosen == 'off':
        return None
    if chosen:
        return Path(chosen)
    base = os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache'
    return Path(base) / 'agv_nodes'


@functools.cache
def code_digest() -> str:
    """Return a digest of every Python source and data file of the package, as installed."""
    h = hashlib.sha256()
    for path in sorted(PACKAGE.rglob('*')):
        if path.suffix in ('.py', '.yaml') and '__pycache__' not in path.parts:
            h.update(str(path.relative_to(PACKAGE)).encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def cached(kind: str, inputs: str, compute: Callable[[], Any]) -> Any:
    """Return `compute()` (a JSON value) for `inputs`, from the cache when it has it."""
    key = hashlib.sha256(f'{kind}\n{code_digest()}\n{inputs}'.encode()).hexdigest()
    if key in _memory:
        return _memory[key]
    folder = cache_dir()
    entry = folder / kind / f'{key}.json' if folder is not None else None
    if entry is not None:
        try:
            _memory[key] = json.loads(entry.read_text())
            return _memory[key]
        except (OSError, ValueError):
            pass  # not there yet (or unreadable): compute it
    _memory[key] = value = compute()
    if entry is not None:
        try:
            entry.parent.mkdir(parents=True, exist_ok=True)
            # written whole, then renamed: a concurrent reader sees all of it or nothing
            with tempfile.NamedTemporaryFile('w', dir=entry.parent, delete=False,
                                             suffix='.tmp') as tmp:
                json.dump(value, tmp)
            os.replace(tmp.name, entry)
        except OSError:
            pass
    return value
