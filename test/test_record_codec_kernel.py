"""The record codec's C fast paths give exactly what the generated Python gives.

`agv_nodes/records/_codec.c` (built by `pip install -e .`) seals and checks whole records for
the ports wherever it was built; records/fast_paths.py's generated Python is what it stands in
for. Both are fed the same inputs here, good and bad: the same bytes, or the same dict (the
same keys in the same order, values of the same types), or None from both. test_delivery_paths
holds each of them to the general path.
"""

from __future__ import annotations

import random

import pytest
from record_values import field_value

from agv_nodes.records import codec, compiled_paths
from agv_nodes.records.compiled_paths import compiled_port_paths, port_spec
from agv_nodes.records.e2e import record_crc
from agv_nodes.records.fast_paths import compile_port_paths

pytestmark = pytest.mark.timeout(120)

SCHEMAS = list(codec())
INTEGRITY = ('e2e', 'none')


def _exactly(value):
    """Return a result with the types of its values and the order of its keys made visible."""
    if isinstance(value, dict):
        return [(type(k), k, type(v), v) for k, v in value.items()]
    return type(value), value


def test_the_codec_kernel_is_built_and_the_ports_use_it():
    assert compiled_paths.compiled is not None, 'agv_nodes/records/_codec.c was not built'
    for schema in SCHEMAS:
        for integrity in INTEGRITY:
            seal, check = schema.port_paths(integrity)
            assert type(seal.__self__) is compiled_paths.compiled.Port
            assert check.__self__ is seal.__self__


def test_without_the_kernel_the_generated_python_runs(monkeypatch):
    monkeypatch.setattr(compiled_paths, 'compiled', None)
    assert compiled_port_paths(SCHEMAS[0], 'e2e') is None


@pytest.mark.parametrize('integrity', INTEGRITY)
@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
def test_c_seals_as_the_generated_python_seals(schema, integrity):
    c_seal, _ = compiled_port_paths(schema, integrity)
    py_seal, _ = compile_port_paths(schema, integrity)
    rng = random.Random(schema.data_id)
    sealed = 0
    for i in range(3000):
        values = {f.name: field_value(f, rng, i % 2 == 0, wild=True) for f in schema.fields}
        if i % 11 == 0:
            values.pop(rng.choice(schema.fields).name)  # a field missing
        elif i % 13 == 0:
            values['no_such_field'] = 1
        elif i % 17 == 0:
            values = dict(reversed(values.items()))  # another order: the same record
        counter = rng.choice((0, 1, 255, rng.randrange(256), -1, 256, True, 2 ** 70))
        got, want = c_seal(values, counter), py_seal(values, counter)
        assert _exactly(got) == _exactly(want), (values, counter)
        sealed += want is not None
    defaults = schema.defaults()
    assert _exactly(c_seal(defaults, 9)) == _exactly(py_seal(defaults, 9))
    assert c_seal(list(defaults.items()), 9) is None  # not a dict
    assert sealed > 100


def _with_crc(schema, data: bytes) -> bytes:
    """Return `data` with a right CRC where the schema carries one (so the fields get judged)."""
    if not schema.protected:
        return data
    return data[:15] + bytes((record_crc(schema.data_id, data[:15]),))


@pytest.mark.parametrize('integrity', INTEGRITY)
@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
def test_c_checks_as_the_generated_python_checks(schema, integrity):
    _, c_check = compiled_port_paths(schema, integrity)
    py_seal, py_check = compile_port_paths(schema, integrity)
    rng = random.Random(schema.data_id + 1)
    taken = refused = 0
    for i in range(4000):
        kind = i % 6
        good = py_seal({f.name: field_value(f, rng, True) for f in schema.fields},
                       rng.randrange(256))
        if kind == 0:
            data = good
        elif kind == 1:  # one bit flipped
            bit = rng.randrange(128)
            data = bytes(b ^ (1 << bit % 8) if k == bit // 8 else b for k, b in enumerate(good))
        elif kind == 2:  # any bytes, with a good CRC: spare bits, ranges, enum codes judged
            data = bytes(rng.randrange(256) for _ in range(16))
            data = _with_crc(schema, data) if integrity == 'e2e' else data
        elif kind == 3:
            data = bytes(rng.randrange(256) for _ in range(16))
        elif kind == 4:
            data = good[:rng.randrange(16)] + bytes(rng.randrange(2) * 2)
        else:
            data = rng.choice([bytearray(good), memoryview(good), list(good), None, 'x' * 16])
        got, want = c_check(data), py_check(data)
        assert _exactly(got) == _exactly(want), data
        taken += want is not None
        refused += want is None
    assert taken > 100 and refused > 100


def test_a_spec_that_does_not_fit_a_record_is_refused():
    fields, *rest = port_spec(codec()['traction_status'], 'e2e')
    first = fields[0]
    with pytest.raises(ValueError, match='does not fit a record'):
        compiled_paths.compiled.Port(((first[0], 15, 1, *first[3:]),), *rest)
    with pytest.raises(ValueError, match='does not fit a record'):
        compiled_paths.compiled.Port(((first[0], 0, 0, 6, 7, 3, *first[6:]),), *rest)
    with pytest.raises(TypeError):
        compiled_paths.compiled.Port(((1, *first[1:]),), *rest)
    with pytest.raises(ValueError, match='256-byte table'):
        compiled_paths.compiled.Port(fields, *rest[:4], b'\0' * 255, rest[5])
    with pytest.raises(TypeError):
        compiled_paths.compiled.Port(fields, *rest, extra=1)
