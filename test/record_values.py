"""Field values for the codec tests: mostly valid, sometimes anything a core or a fuzzer passes.

Shared by test_records, test_delivery_paths and test_record_codec_kernel, which feed the same
kinds of value to the general path, the generated fast paths and their C twins.
"""

from __future__ import annotations

import random
from typing import Any


def field_value(f: Any, rng: random.Random, valid: bool = False, wild: bool = False) -> Any:
    """Draw a value for field `f` (`valid`: always one it can encode).

    Mostly valid, sometimes a bool, a special's name, an enum code, out of range or of the
    wrong type; `wild` adds ints beyond 64 bits, None and bytes.
    """
    roll = 0.0 if valid else rng.random()
    if f.encoding == 'enum':
        if roll < 0.7:
            return rng.choice(list(f.values))
        return rng.choice([rng.choice(list(f.names)), 'no such name', 3.5, None,
                           *((b'x',) if wild else ())])
    if roll < 0.6:
        return rng.randint(f.lo, f.hi)
    if roll < 0.7:
        return rng.choice([True, False])
    if roll < 0.8 and f.special:
        k = rng.choice(list(f.special))
        return rng.choice([k, f.special[k]])
    return rng.choice([f.lo - 1, f.hi + 1, -40000, 70000, 1.0, '7',
                       *((2 ** 70, -2 ** 70, None) if wild else ())])
