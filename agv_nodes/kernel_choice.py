"""The `kernels` parameter: compiled C for a hot loop, or the Python code it stands in for.

Each package part with a C kernel (the world's physics and optics, the position sensor's
THRESH, the record codec) keeps its Python code as the reference and its C code as the same
arithmetic, tested to give the same results. Where a node has the parameter (the world, the
position sensor), `auto` (default) takes the C code where it was built, `c` insists on it and
`python` never uses it; the codec, below every node, takes its C wherever it was built. The
extensions are optional: a machine without a C compiler installs the package without them and
runs the Python code.
"""

from __future__ import annotations

from types import ModuleType

CHOICES = ('auto', 'c', 'python')


def select(compiled: ModuleType | None, choice: str, what: str) -> ModuleType | None:
    """Return `compiled` if `choice` asks for it (None: the Python code); `what` names it."""
    if choice not in CHOICES:
        raise ValueError(f'{what} kernels: {choice!r} is not one of {", ".join(CHOICES)}')
    if choice == 'python':
        return None
    if choice == 'c' and compiled is None:
        raise ValueError(f"{what} kernels: 'c' asks for the compiled kernels, which are not "
                         'built (pip install -e . builds them with the C compiler)')
    return compiled
