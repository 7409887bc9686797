"""The ports' fast paths in C (`_codec.c`, built by setup.py), where built.

`compile_port_paths` (records/fast_paths.py) generates straight-line Python for one schema and
integrity mode; `compiled_port_paths` gives a C `Port` that does the same checks in the same
order and returns the same bytes and field dicts (test/test_record_codec_kernel.py), at a
fraction of the cost: the codec runs on every record a node or the lock-step harness sends and
takes. Both return None for anything they are not sure of, and the general path of
records/schema.py then judges and names it. The codec has no parameter of its own: it sits
below every node, and C or Python changes only speed, so the C code runs wherever it was built
(agv_nodes/kernel_choice.py: an install without a C compiler runs the Python).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from agv_nodes.records.e2e import CRC_TABLE, INIT, XOROUT
from agv_nodes.records.fast_paths import unpacked

try:
    # a C extension setup.py builds, with no stub: mypy reads no .so
    from agv_nodes.records import _codec as compiled  # type: ignore[attr-defined]
except ImportError:  # not built (no C compiler at install): the generated Python runs
    compiled = None

RECORD_LENGTH = 16
FIELD_KINDS = {'flag': 1, 'enum': 2}  # any other encoding: an integer (0)


def port_spec(schema: Any, integrity: str) -> tuple:
    """Return the arguments of `_codec.Port` for `schema` in `integrity` ('e2e' or 'none')."""
    fields = []
    for f in schema.fields:
        signed, possible = unpacked(f)
        enum = f.encoding == 'enum'
        fields.append((f.name, f.byte - 1, int(f.n_bytes == 2), f.lo_bit, (1 << f.width) - 1,
                       f.width, FIELD_KINDS.get(f.encoding, 0), int(signed), f.lo, f.hi,
                       frozenset(f.special) if f.special else None,
                       dict(f.values) if enum else None, dict(f.names) if enum else None,
                       int(not (f.lo <= possible[0] and possible[1] <= f.hi))))
    spare_bytes = 14 if schema.protected else RECORD_LENGTH
    spare = bytes(~used & 0xFF for used in schema.used[:spare_bytes])
    return (tuple(fields), schema.protected and integrity == 'e2e', schema.protected,
            CRC_TABLE[INIT ^ schema.data_id], XOROUT, bytes(CRC_TABLE), spare)


def compiled_port_paths(schema: Any, integrity: str) -> tuple[Callable, Callable] | None:
    """(seal, check) in C for `schema` in `integrity`, or None where `_codec` is not built."""
    if compiled is None:
        return None
    port = compiled.Port(*port_spec(schema, integrity))
    return port.seal, port.check
