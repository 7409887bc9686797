"""The ports' fast paths and the harness's shared decoding agree with the checked paths.

`RecordWriter.pack` and `RecordReader.accept` try fast paths for whole records first (C where
built, records/compiled_paths.py; else generated Python, records/fast_paths.py
`compile_port_paths`; both are held to the general path here) and take the general codec on
None; the lock-step
harness decodes a record once for all its readers. Whatever a fast path returns must be what the
general path makes of the same input, and every reader must count, name and keep exactly what
it would alone.
"""

from __future__ import annotations

import random

import pytest
from record_values import field_value

from agv_nodes.harness import Harness, truck
from agv_nodes.records import RecordError, RecordReader, RecordWriter, codec
from agv_nodes.records.compiled_paths import compiled_port_paths
from agv_nodes.records.e2e import Sequence
from agv_nodes.records.fast_paths import compile_port_paths

SCHEMAS = list(codec())
INTEGRITY = ('e2e', 'none')
# the ports' fast paths: C (test_record_codec_kernel.py checks it is built) and Python
PATHS = {'c': compiled_port_paths, 'python': compile_port_paths}


def _values(schema, rng: random.Random, i: int) -> dict:
    valid = i % 3 == 0
    values = {f.name: field_value(f, rng, valid) for f in schema.fields
              if i % 5 or rng.random() < 0.9}  # every fifth may leave fields to defaults
    if i % 7 == 0:
        values['no_such_field'] = 1
    return values


@pytest.mark.parametrize('paths', PATHS)
@pytest.mark.parametrize('integrity', INTEGRITY)
@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
def test_seal_gives_what_encode_gives(schema, integrity, paths):
    seal, _check = PATHS[paths](schema, integrity)
    rng = random.Random(schema.data_id)
    taken = 0
    for i in range(600):
        values = _values(schema, rng, i)
        counter = rng.choice((0, 1, 254, 255, rng.randrange(256), -1, 256))
        fast = seal(values, counter)
        try:
            general = schema.encode(values, integrity=integrity, counter=counter)
        except RecordError:
            assert fast is None, (values, counter)
            continue
        if fast is not None:
            taken += 1
            assert type(fast) is bytes and fast == general, (values, counter)
    full = schema.defaults()
    assert seal(full, 7) == schema.encode(full, integrity=integrity, counter=7)
    assert seal({**full, 'no_such_field': 0}, 7) is None  # the general path names it
    assert taken > 0


@pytest.mark.parametrize('paths', PATHS)
@pytest.mark.parametrize('integrity', INTEGRITY)
@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
def test_check_gives_what_decode_gives(schema, integrity, paths):
    _seal, check = PATHS[paths](schema, integrity)
    rng = random.Random(schema.data_id + 1)
    taken = 0
    for i in range(1500):
        good = schema.encode({f.name: field_value(f, rng, True) for f in schema.fields},
                             integrity=integrity, counter=rng.randrange(256))
        kind = i % 5
        if kind == 0:
            data = good
        elif kind == 1:  # one bit flipped
            bit = rng.randrange(128)
            data = bytes(b ^ (1 << bit % 8) if k == bit // 8 else b for k, b in enumerate(good))
        elif kind == 2:
            data = bytes(rng.randrange(256) for _ in range(16))
        elif kind == 3:
            data = good[:rng.randrange(16)] + bytes(rng.randrange(2) * 2)
        else:
            data = bytearray(good)  # the general path takes it
        fast = check(data)
        try:
            general = schema.decode(data, integrity=integrity)
        except RecordError:
            assert fast is None, data.hex()
            continue
        if fast is not None:
            taken += 1
            assert fast == general, data.hex()
        else:
            assert type(data) is not bytes, data.hex()  # every valid record of bytes is fast
    assert taken > 0


def _stream(schema, integrity, rng: random.Random) -> list[bytes | bytearray]:
    """Return a writer's records with losses, repeats, replays, jumps, corruption and restarts."""
    writer = RecordWriter(schema, integrity)
    out: list[bytes | bytearray] = []
    for _ in range(1200):
        raw = writer.pack({f.name: field_value(f, rng, True) for f in schema.fields})
        roll = rng.random()
        if roll < 0.05:
            continue  # lost
        if roll < 0.08 and out:
            out.append(rng.choice(out[-20:]))  # repeated or replayed
        elif roll < 0.11:
            out.append(bytes(b ^ 0x10 if k == rng.randrange(16) else b
                             for k, b in enumerate(raw)))
        elif roll < 0.12:
            writer.counter = rng.randrange(256)  # a jump (a restart, a foreign writer)
        elif roll < 0.13:
            out.append(bytearray(raw))
        out.append(raw)
    return out


@pytest.mark.parametrize('integrity', INTEGRITY)
@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
def test_reader_accounting_is_the_checked_paths(schema, integrity):
    """A reader on the fast paths counts as one on the general codec and e2e.py alone."""
    fast, general = RecordReader(schema, integrity), RecordReader(schema, integrity)
    rng = random.Random(schema.data_id + 2)
    for k, data in enumerate(_stream(schema, integrity, rng)):
        if k % 97 == 0:
            fast.resync()
            general.resync()
        assert fast.accept(data, k) == _checked_accept(general, data, k), k
        assert _state(fast) == _state(general), k


def _checked_accept(r: RecordReader, data, now_ns: int) -> dict | None:
    """RecordReader.accept on the general codec, every counter through SequenceCheck.check."""
    try:
        fields = r.schema.decode(data, integrity=r.integrity)
    except RecordError as exc:
        r._reject(exc.code.value, str(exc))
        return None
    initial = False
    if r.schema.protected and r.integrity == 'e2e':
        counter = data[14]
        verdict = r.sequence.check(counter)
        if verdict is Sequence.REPEATED:
            r._reject('repeated_counter', f'{r.schema.name}: repeated counter {counter} (not '
                      'new data)')
            return None
        if verdict is Sequence.WRONG_SEQUENCE:
            r._reject('wrong_sequence', f'{r.schema.name}: counter {counter} out of sequence '
                      f'(last accepted {r.sequence.last})')
            return None
        if verdict is Sequence.SYNC:
            r._reject('resyncing', f'{r.schema.name}: counter {counter} continues a run after '
                      f'a jump (resynchronising after {r.sequence.sync_records}, not acted on)')
            return None
        initial = verdict is Sequence.INITIAL
    r.restarted = r.accepted > 0 and (initial or r._new_writer)
    r.restarts += r.restarted
    r._new_writer = False
    r.fields, r.raw, r.stamp_ns = fields, bytes(data), now_ns
    r.accepted += 1
    return fields


def _state(r: RecordReader) -> tuple:
    return (r.fields, r.raw, r.stamp_ns, r.accepted, r.restarts, r.restarted, dict(r.rejects),
            r.last_error, r.last_reason, r.lost, r.sequence.last, dict(r.sequence.runs),
            r.sequence.resyncs)


def _readers(h: Harness) -> dict:
    out = {('world', name): r for name, r in h.world_readers.items()}
    out.update({(m.core.node, name): r for m in h.members for name, r in m.readers.items()})
    return out


def _each_reader_decodes(h: Harness):
    route = h._route

    def unshared(record: str) -> tuple:
        world_reader, readers, _decode = route(record)
        h._routes[record] = out = (world_reader, readers, None)
        return out

    return unshared


def test_shared_decoding_keeps_every_readers_accounting():
    """One decoding for all the readers of a record (wheel_odometry: three), each counts."""
    runs = []
    for shared in (True, False):
        h = truck('demo_1983', seed=3)
        if not shared:  # every reader decodes for itself
            h._route = _each_reader_decodes(h)
        rng = random.Random(5)
        received: list[tuple[str, bytes]] = []
        h.taps.append(lambda record, raw, now, into=received: into.append((record, raw)))
        for k in range(300):
            h.step()
            if k % 10 == 0 and received:
                record, raw = rng.choice(received[-30:])
                if rng.random() < 0.5:  # corrupt it, else a replay
                    raw = bytes(b ^ (1 << rng.randrange(8)) if i == rng.randrange(16) else b
                                for i, b in enumerate(raw))
                h.inject(record, raw)
        assert (h._routes['wheel_odometry'][2] is not None) is shared
        fields = {key: dict(r.fields or {}) for key, r in _readers(h).items()}
        runs.append(({key: _state(r)[1:] for key, r in _readers(h).items()}, fields,
                     h.events, h.world.time))
    assert runs[0] == runs[1]
    odometry = [r for (_node, name), r in _readers(h).items() if name == 'wheel_odometry']
    assert len(odometry) == 3 and all(r.accepted for r in odometry)
    assert any(r.rejected for r in _readers(h).values())


class _Echo:
    """A stand-in core that answers each record it reads with the one it writes: a loop."""

    period = 0.01

    def __init__(self, node: str, reads: str, writes: str, start: bool) -> None:
        self.node, self.reads, self.writes, self.start = node, reads, writes, start
        self.answered = 0

    def _record(self) -> dict:
        return {self.writes: {f.name: f.default for f in codec()[self.writes].fields}}

    def on_record(self, record: str, fields: dict, now: float) -> dict | None:
        if record != self.reads:
            return None
        self.answered += 1
        return self._record()

    def tick(self, now: float) -> dict | None:
        return self._record() if self.start else None


def test_records_that_keep_triggering_records_stop_the_harness():
    """Two cores answering each other for ever: a clear error, not a recursion overflow."""
    h = truck('demo_1983', seed=1)
    loop = Harness(h.world, [
        _Echo('executive', 'navigation_status', 'navigation_command', start=True),
        _Echo('navigation', 'navigation_command', 'navigation_status', start=False)])
    with pytest.raises(RuntimeError, match='records keep triggering records'):
        loop.run(0.1)
    assert loop._depth == 0
