"""Malformed records for the fuzz tests: hypothesis strategies of defects, applied per topic.

Every recipe makes a defect (wrong lengths, random bytes, bad CRC, repeated or skipped
counters, spare bits set, out-of-range values). Recipes that need a live counter start from
the record the reader accepted last (`genuine`). What a reader must do with each is not
decided here but by the oracle written apart from the codec and the reader
(test/record_oracle.py): a skipped counter is refused, unless it completes a resynchronisation
run, which the rules take as a writer. test/fuzz_session.py sends every recipe drawn through a
live graph and keeps the exact count each reader must show (test/test_bad_input_dds.py,
bench/fuzz_bench.py).

What is left out, and why: 16 random bytes that happen to carry a valid CRC-8 (1 in 256) and a
counter within 15 of the last genuine one are, by construction, a record E2E cannot tell from a
genuine one; and on the unprotected hardware topics any well-formed 16 bytes are a valid record
(an ADC snapshot may hold any values). Those residual risks are the ones docs/hardware.md names;
the strategies below keep to defects a port can detect.
"""

from __future__ import annotations

from dataclasses import dataclass

from hypothesis import strategies as st

from agv_nodes.records.e2e import record_crc
from agv_nodes.records.errors import RecordError
from agv_nodes.records.schema import COUNTER_BYTE, CRC_BYTE, RecordSchema


@dataclass(frozen=True)
class Recipe:
    """One defect: its kind and the numbers it needs."""

    kind: str
    length: int = 16
    noise: bytes = b''
    xor: int = 1
    skip: int = 16
    position: int = 0  # spare bit index, or bad-value index


def spare_bits(schema: RecordSchema) -> list[tuple[int, int]]:
    """(byte index from 0, bit) of every bit no field claims, outside the E2E bytes."""
    last = 14 if schema.protected else 16
    return [(i, b) for i in range(last) for b in range(8)
            if not (schema.used[i] >> b) & 1]


def bad_values(schema: RecordSchema) -> list[tuple[int, int, int]]:
    """(byte index from 0, mask, raw byte bits) that put a one-byte field out of range."""
    out = []
    for f in schema.fields:
        if f.n_bytes != 1:
            continue
        for raw in range(1 << f.width):
            signed = f.encoding == 'twos_complement' and raw >> (f.width - 1)
            if not f.valid(raw - (1 << f.width) if signed else raw):
                out.append((f.byte - 1, f.mask, raw << f.lo_bit))
    return out


def recipes(schema: RecordSchema) -> st.SearchStrategy[Recipe]:
    """Return the defects that apply to `schema`'s records."""
    options = [
        st.builds(Recipe, kind=st.just('wrong_length'),
                  length=st.integers(0, 40).filter(lambda n: n != 16)),
    ]
    if schema.protected:
        options += [
            st.builds(Recipe, kind=st.just('random_bytes'), noise=st.binary(min_size=16,
                                                                            max_size=16)),
            st.builds(Recipe, kind=st.just('bad_crc'), xor=st.integers(1, 255)),
            st.builds(Recipe, kind=st.just('repeated_counter')),
            st.builds(Recipe, kind=st.just('skipped_counter'), skip=st.integers(16, 240)),
        ]
    return st.one_of(options + field_defects(schema))


def field_defects(schema: RecordSchema) -> list[st.SearchStrategy[Recipe]]:
    """Return the recipes that set a spare bit or put a value a field may not hold."""
    out = []
    if spare_bits(schema):
        out.append(st.builds(Recipe, kind=st.just('spare_set'),
                             position=st.integers(0, len(spare_bits(schema)) - 1)))
    if bad_values(schema):
        out.append(st.builds(Recipe, kind=st.just('bad_value'),
                             position=st.integers(0, len(bad_values(schema)) - 1)))
    return out


def _seal(schema: RecordSchema, data: bytearray) -> bytes:
    if schema.protected:
        data[CRC_BYTE - 1] = record_crc(schema.data_id, bytes(data[:15]))
    return bytes(data)


def apply(schema: RecordSchema, recipe: Recipe, genuine: bytes | None) -> bytes:
    """Return the malformed bytes for `recipe`, starting from the latest genuine record."""
    base = bytearray(genuine if genuine and len(genuine) == 16 else schema.encode())
    if recipe.kind == 'wrong_length':
        return bytes((base * 3)[:recipe.length])
    if recipe.kind == 'random_bytes':
        data = bytearray(recipe.noise)
        if data[CRC_BYTE - 1] == record_crc(schema.data_id, bytes(data[:15])):
            data[CRC_BYTE - 1] ^= 0xFF  # a CRC collision is not a detectable defect
        return bytes(data)
    if recipe.kind == 'bad_crc':
        base[CRC_BYTE - 1] ^= recipe.xor
        return bytes(base)
    if recipe.kind == 'repeated_counter':  # a replay: the reader has this counter already
        return bytes(base)
    if recipe.kind == 'skipped_counter':
        base[COUNTER_BYTE - 1] = (base[COUNTER_BYTE - 1] + recipe.skip) & 0xFF
        return _seal(schema, base)
    if recipe.kind == 'spare_set':
        i, bit = spare_bits(schema)[recipe.position]
        base[i] |= 1 << bit
        return _seal(schema, base)
    if recipe.kind == 'bad_value':
        i, mask, bits = bad_values(schema)[recipe.position]
        base[i] = (base[i] & ~mask & 0xFF) | bits
        return _seal(schema, base)
    raise ValueError(recipe.kind)


def rejected(schema: RecordSchema, data: bytes, integrity: str = 'e2e') -> bool:
    """Return True when the codec alone refuses `data` (sequence defects need reader state)."""
    try:
        schema.decode(data, integrity=integrity if schema.protected else 'none')
    except RecordError:
        return True
    return False
