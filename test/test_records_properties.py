"""Property tests: every record round-trips; fuzzed bytes decode exactly or raise.

And the E2E sequence check: a rejected record never changes what the genuine records do.
"""

from __future__ import annotations

from collections import Counter

from hypothesis import event, given, settings
from hypothesis import strategies as st
import pytest
from record_fuzz import Recipe, apply, field_defects, recipes, rejected

from agv_nodes.records import RecordError, RecordReader, RecordWriter, codec
from agv_nodes.records.e2e import record_crc
from agv_nodes.records.ports import CORRUPT
from agv_nodes.records.schema import Field, RecordSchema

C = codec()
SCHEMAS = list(C)


def field_values(f: Field) -> st.SearchStrategy:
    if f.encoding == 'enum':
        return st.sampled_from(sorted(f.values))
    valid = st.integers(f.lo, f.hi)
    if f.special:
        valid = st.one_of(valid, st.sampled_from(sorted(f.special)))
    return valid


def records(schema: RecordSchema) -> st.SearchStrategy:
    return st.fixed_dictionaries({f.name: field_values(f) for f in schema.fields})


@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
@given(data=st.data(), counter=st.integers(0, 255),
       integrity=st.sampled_from(['e2e', 'none']))
def test_round_trip(schema, data, counter, integrity):
    fields = data.draw(records(schema))
    raw = schema.encode(fields, integrity=integrity, counter=counter)
    assert len(raw) == 16
    assert schema.decode(raw, integrity=integrity) == fields


@pytest.mark.parametrize('schema', SCHEMAS, ids=lambda s: s.name)
@given(raw=st.binary(min_size=0, max_size=20), integrity=st.sampled_from(['e2e', 'none']))
def test_fuzzed_bytes_decode_exactly_or_raise(schema, raw, integrity):
    """No silent wrong value: whatever decodes re-encodes to the very same 16 bytes."""
    try:
        fields = schema.decode(raw, integrity=integrity)
    except RecordError as exc:
        assert exc.code.value in CORRUPT, str(exc)  # what a port counts it as
        return
    counter = raw[14] if schema.protected and integrity == 'e2e' else 0
    assert schema.encode(fields, integrity=integrity, counter=counter) == raw


@pytest.mark.parametrize('schema', [s for s in SCHEMAS if s.protected], ids=lambda s: s.name)
@given(data=st.data(), flip_byte=st.integers(0, 15), flip_bits=st.integers(1, 255))
def test_any_corruption_of_a_protected_record_is_caught(schema, data, flip_byte, flip_bits):
    """CRC-8 catches every single-byte corruption (any burst within one byte)."""
    raw = bytearray(schema.encode(data.draw(records(schema)), counter=5))
    raw[flip_byte] ^= flip_bits
    with pytest.raises(RecordError):
        schema.decode(bytes(raw))


def sequence_model(counters, max_delta=15, sync_records=3):
    """Apply the reader's counter rule, written out plainly: each verdict, and the lost count."""
    last, runs, lost, out = None, {}, 0, []
    for c in counters:
        verdict = 'accepted'
        if last is None:
            last = c
        elif (d := (c - last) % 256) == 0:
            verdict = 'repeated_counter'
        elif d <= max_delta:
            last, lost = c, lost + d - 1
        elif d >= 256 - max_delta:
            verdict = 'wrong_sequence'  # went back
        elif (c - 1) % 256 in runs:
            length = runs.pop((c - 1) % 256) + 1
            if length >= sync_records:
                last = c
            else:
                runs[c], verdict = max(runs.get(c, 0), length), 'resyncing'
        elif c in runs:
            verdict = 'repeated_counter'
        else:
            runs[c], verdict = 1, 'wrong_sequence'
        if verdict == 'accepted':
            runs = {}
        out.append(verdict)
    return out, lost


@given(steps=st.lists(st.integers(0, 40), min_size=1, max_size=60),
       sync_records=st.integers(2, 5))
def test_reader_sequence_rules(steps, sync_records):
    """Small gaps are accepted and counted; a jump is rejected until N records confirm it."""
    schema = C['navigation_status']
    writer = RecordWriter(schema)
    reader = RecordReader(schema, sync_records=sync_records)
    counters = []
    for step in steps:
        for _ in range(step):
            writer.pack({})  # records that never reach the reader
        raw = writer.pack({'last_marker': 1})
        counters.append(raw[14])
        before = reader.rejects.copy()
        got = reader.accept(raw, 0)
        verdict, _ = sequence_model(counters, sync_records=sync_records)
        if verdict[-1] == 'accepted':
            assert got is not None and reader.raw == raw
        else:
            assert got is None
            assert reader.rejects - before == Counter({verdict[-1]: 1})
    verdicts, lost = sequence_model(counters, sync_records=sync_records)
    assert reader.accepted == verdicts.count('accepted')
    assert reader.lost == lost


def test_reader_rejects_replay_and_counts_reasons():
    schema = C['traction_command']
    writer = RecordWriter(schema)
    reader = RecordReader(schema)
    first = writer.pack({'demand': 20})
    assert reader.accept(first, 1)['demand'] == 20
    assert reader.accept(first, 2) is None  # replayed: not new data
    bad = bytearray(writer.pack({'demand': 30}))
    bad[15] ^= 1
    assert reader.accept(bytes(bad), 3) is None
    assert reader.accept(b'\x00' * 15, 4) is None
    assert dict(reader.rejects) == {'repeated_counter': 1, 'bad_crc': 1, 'wrong_length': 1}
    assert reader.fields == {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': 20,
                             'executive_priority': 0}
    assert reader.stamp_ns == 1 and 'wrong' not in reader.last_error


def test_reader_none_mode_accepts_plain_thesis_records():
    schema = C['traction_link']
    reader = RecordReader(schema, integrity='none')
    assert reader.accept(bytes([0x14]) + bytes(15), 0) == {
        'executive_priority': 0, 'reverse': 0, 'speed': 20, 'stop_in': 0}
    assert reader.accept(bytes([0x14]) + bytes(15), 1) is not None  # no counter to repeat


# -- the generator itself (no DDS): every recipe is a record a port must reject ----------------
FUZZED = [s for s in SCHEMAS if s.kind != 'ground_truth']


@pytest.mark.parametrize('schema', FUZZED, ids=[s.name for s in FUZZED])
def test_every_recipe_is_rejected_by_a_port(schema):
    @settings(max_examples=100, derandomize=True, database=None)
    @given(recipe=recipes(schema), demand=st.integers(0, 3))
    def check(recipe, demand):
        reader = RecordReader(schema)
        genuine = schema.encode(integrity='e2e', counter=demand) if schema.protected \
            else schema.encode(integrity='none')
        assert reader.accept(genuine, 0) is not None
        bad = apply(schema, recipe, genuine)
        if recipe.kind in ('repeated_counter', 'skipped_counter'):
            assert not rejected(schema, bad)  # only the sequence check can catch these
        assert reader.accept(bad, 1) is None, (recipe, bad.hex())

    check()


# -- the sequence check: a rejected record never costs a genuine one -------------------------
W = 15  # the readers' max_delta: the window ahead, and how far back counts as "went back"
SEQUENCED = [C['traction_command'], C['navigation_status']]
DATA_IDS = sorted({s.data_id for s in SCHEMAS if s.protected})
CODEC_REFUSED = ('bad_crc', 'wrong_data_id', 'truncated', 'over_long', 'malformed')
SEQUENCE_FUZZ = ('repeated', 'stale', 'out_of_window', 'gap_forged')


def sealed(schema: RecordSchema, base: bytes, counter: int) -> bytes:
    """Return `base` with counter `counter` and a valid CRC: well-formed, maybe forged."""
    data = bytearray(base)
    data[14] = counter
    data[15] = record_crc(schema.data_id, bytes(data[:15]))
    return bytes(data)


@st.composite
def genuine_streams(draw, schema: RecordSchema) -> list[tuple]:
    """One writer's records as the reader receives them, through losses and restarts.

    Each item is ('record', raw, counters lost just before it) or ('resync',) where the node
    is told its writer changed. The writer may start anywhere (near the 255 -> 0 wrap too).
    """
    payload = draw(records(schema))
    writer = RecordWriter(schema)
    writer.counter = draw(st.one_of(st.integers(0, 255), st.integers(236, 255)))
    ops = draw(st.lists(st.one_of(
        st.tuples(st.just('send'), st.integers(1, 8)),
        st.tuples(st.just('lose'), st.integers(1, 2 * W + 10)),  # inside and beyond the window
        st.tuples(st.just('restart'), st.just(0)),  # a new writer counts from 0 again
        st.tuples(st.just('restart_told'), st.just(0)),  # ... and the node calls resync()
    ), min_size=1, max_size=10))
    out: list[tuple] = []
    lost: list[int] = []
    for op, n in [*ops, ('send', 5)]:
        if op == 'send':
            for _ in range(n):
                out.append(('record', writer.pack(payload), tuple(lost)))
                lost = []
        elif op == 'lose':
            lost += [writer.pack(payload)[14] for _ in range(n)]
        else:
            writer, lost = RecordWriter(schema), []
            if op == 'restart_told':
                out.append(('resync',))
    return out


def snapshot(reader: RecordReader) -> tuple:
    """Everything a reader keeps but its rejection counts and resynchronisation runs."""
    return (reader.sequence.last, reader.sequence.lost, reader.accepted, reader.fields,
            reader.raw, reader.stamp_ns)


def malformations(schema: RecordSchema) -> st.SearchStrategy[Recipe]:
    """Return record_fuzz's defects that the codec refuses by itself (no counter involved)."""
    options = [st.builds(Recipe, kind=st.just('random_bytes'),
                         noise=st.binary(min_size=16, max_size=16))]
    return st.one_of(options + field_defects(schema))


class Fuzzer:
    """Draws records a port must reject, given what the genuine stream has shown so far."""

    def __init__(self, data, schema: RecordSchema, stream: list[tuple]) -> None:
        self.data, self.schema = data, schema
        # every counter the reader will ever see from the genuine writer(s)
        self.genuine = {item[1][14] for item in stream if item[0] == 'record'}
        self.forged: set[int] = set()
        self.epoch: list[bytes] = []  # genuine records since the writer last restarted
        self.gap: tuple[int, ...] = ()  # counters the latest loss skipped

    def seen(self, item: tuple) -> None:
        """Note a genuine stream item once the readers have had it."""
        if item[0] == 'resync':
            self.epoch, self.gap = [], ()
        else:
            if self.epoch and item[1][14] != (self.epoch[-1][14] + 1) % 256 and not item[2]:
                self.epoch = []  # a restart nobody was told of
            self.epoch.append(item[1])
            self.gap = item[2] or self.gap

    def isolated(self, c: int) -> bool:
        """Tell whether forged counter `c` neither continues nor is continued by another counter.

        A forged record next to a genuine counter would be the genuine record in effect, and
        N forged in a row would be a writer: E2E cannot tell either, by design.
        """
        near = {(c - 1) % 256, (c + 1) % 256}
        return c not in self.genuine and not near & (self.genuine | self.forged)

    def draw(self, twin: RecordReader) -> tuple[str, bytes] | None:
        """One fuzzed record, or None when its kind cannot be made right now."""
        schema, data = self.schema, self.data
        base = self.epoch[-1] if self.epoch else schema.encode(counter=data.draw(
            st.integers(0, 255)))
        kind = data.draw(st.sampled_from(CODEC_REFUSED + SEQUENCE_FUZZ))
        if kind == 'bad_crc':
            bad = bytearray(base)
            bad[15] ^= data.draw(st.integers(1, 255))
            return kind, bytes(bad)
        if kind == 'wrong_data_id':
            other = data.draw(st.sampled_from([i for i in DATA_IDS if i != schema.data_id]))
            bad = bytearray(base)
            bad[15] = record_crc(other, base[:15])
            if bad[15] == base[15]:
                bad[15] ^= 0xFF  # the two data_ids collide on these bytes: not detectable
            return kind, bytes(bad)
        if kind == 'truncated':
            return kind, base[:data.draw(st.integers(0, 15))]
        if kind == 'over_long':
            return kind, base + data.draw(st.binary(min_size=1, max_size=8))
        if kind == 'malformed':
            return kind, apply(schema, data.draw(malformations(schema)), base)
        # Well-formed records: only a reader with a reference can tell them from genuine ones,
        # and only those outside its window (a well-formed record inside it is genuine data).
        last = twin.sequence.last
        if last is None or not self.epoch:
            return None

        def outside(c: int) -> bool:
            return not 1 <= (c - last) % 256 <= W

        if kind == 'repeated':
            options = [self.epoch[-1]]
        elif kind == 'stale':
            latest = self.epoch[-1][14]
            options = [r for r in self.epoch[-2 * W:] if 1 <= (latest - r[14]) % 256 <= W]
        else:
            if kind == 'out_of_window':
                counters = [c for c in range(256) if W < (c - last) % 256 < 256 - W]
            else:  # the counters a loss skipped, forged once the reader has moved past them
                counters = list(self.gap)
            counters = [c for c in counters if outside(c) and self.isolated(c)]
            if not counters:
                return None
            c = data.draw(st.sampled_from(counters))
            self.forged.add(c)
            payload = data.draw(records(schema))
            options = [sealed(schema, schema.encode(payload), c)]
        options = [r for r in options if outside(r[14])]
        if not options:
            return None
        return kind, data.draw(st.sampled_from(options))


@pytest.mark.parametrize('schema', SEQUENCED, ids=lambda s: s.name)
@settings(max_examples=300)
@given(data=st.data())
def test_fuzzed_records_never_change_what_genuine_ones_do(schema, data):
    """No fuzzed record is accepted, and every genuine one fares as it would without them.

    A twin reader gets only the genuine stream; the reader under test gets the same stream
    with fuzzed records between (corrupt CRC, another record's data_id, truncated, over-long,
    malformed, repeated, stale, outside the window, forged into a loss gap), in every state
    the stream reaches: fresh, mid-stream, after a loss, after a writer restart (told or
    not), while resynchronising and after it, near the 255 -> 0 wrap.
    """
    stream = data.draw(genuine_streams(schema))
    twin, reader = RecordReader(schema), RecordReader(schema)
    fuzzer = Fuzzer(data, schema, stream)
    fuzzed = resyncs = 0
    refused = False  # the twin rejected the latest genuine record (a jump, resynchronising)
    for now, item in enumerate([*stream, ('end',)]):
        for _ in range(data.draw(st.integers(0, 3))):
            drawn = fuzzer.draw(twin)
            if drawn is None:
                continue
            kind, bad = drawn
            event(f'fuzz: {kind}')
            event('fuzz while: ' + ('fresh' if twin.sequence.last is None else
                                    'genuine rejected' if refused else 'in step'))
            before = snapshot(reader)
            assert reader.accept(bad, now) is None, (kind, bad.hex())
            assert snapshot(reader) == before, kind  # a rejection moves nothing
            fuzzed += 1
        if item[0] == 'resync':
            twin.resync()
            reader.resync()
        elif item[0] == 'record':
            expected = twin.accept(item[1], now)
            assert reader.accept(item[1], now) == expected, (
                'genuine record fared differently', item[1].hex(), twin.last_reason)
            resyncs += refused and expected is not None
            refused = expected is None
        assert snapshot(reader) == snapshot(twin)
        if item[0] != 'end':
            fuzzer.seen(item)
    assert reader.rejected == twin.rejected + fuzzed
    event(f'genuine records rejected, then accepted again: {min(resyncs, 2)}')
    event(f'counter wrapped: {any(i[0] == "record" and i[1][14] == 0 for i in stream)}')
    assert (reader.accepted, reader.lost) == (twin.accepted, twin.lost)


def test_a_rejected_jump_costs_no_genuine_record():
    """A foreign record that jumps the counter is refused, and the next genuine one is not."""
    schema = C['traction_command']
    writer, reader = RecordWriter(schema), RecordReader(schema)
    for _ in range(3):
        assert reader.accept(writer.pack({'demand': 20}), 0) is not None
    forged = sealed(schema, schema.encode({'demand': 77}), writer.counter + 40)
    assert reader.accept(forged, 1) is None
    assert reader.accept(writer.pack({'demand': 21}), 2)['demand'] == 21
    assert reader.lost == 0 and reader.rejects == Counter({'wrong_sequence': 1})


def test_forged_records_between_genuine_ones_never_resynchronise():
    """Forged records that count on by one among themselves lose to a live genuine writer."""
    schema = C['traction_command']
    writer, reader = RecordWriter(schema), RecordReader(schema)
    reader.accept(writer.pack({'demand': 20}), 0)
    for k in range(10):
        forged = sealed(schema, schema.encode({'demand': 77}), 100 + k)
        assert reader.accept(forged, k) is None
        assert reader.accept(writer.pack({'demand': 20}), k)['demand'] == 20
    assert reader.accepted == 11 and reader.lost == 0 and reader.rejected == 10


def test_replaying_the_last_records_in_order_never_moves_the_reader_back():
    schema = C['navigation_status']
    writer, reader = RecordWriter(schema), RecordReader(schema)
    sent = [writer.pack({'last_marker': k}) for k in range(20)]
    for raw in sent:
        reader.accept(raw, 0)
    for raw in sent[-W - 1:]:
        assert reader.accept(raw, 1) is None
    assert reader.accept(writer.pack({'last_marker': 20}), 2)['last_marker'] == 20
    assert reader.lost == 0


@pytest.mark.parametrize('sync_records', [2, 3, 5])
def test_a_restarted_writer_is_followed_after_n_records_in_a_row(sync_records):
    """Its counter starts again at 0: N records in a row resynchronise, none before is used."""
    schema = C['navigation_status']
    reader = RecordReader(schema, sync_records=sync_records)
    old = RecordWriter(schema)
    old.counter = 100
    reader.accept(old.pack({'last_marker': 1}), 0)
    new = RecordWriter(schema)
    got = [reader.accept(new.pack({'last_marker': 2}), 1) for _ in range(sync_records + 1)]
    assert got[:-2] == [None] * (sync_records - 1) and got[-2] == got[-1] is not None
    assert reader.rejects == Counter({'wrong_sequence': 1, 'resyncing': sync_records - 2})
    assert reader.lost == 0 and reader.sequence.resyncs == 1


def test_resync_on_request_takes_the_next_record():
    schema = C['navigation_status']
    reader, old, new = RecordReader(schema), RecordWriter(schema), RecordWriter(schema)
    old.counter = 100
    reader.accept(old.pack({}), 0)
    reader.resync()
    assert reader.accept(new.pack({}), 1) is not None
    assert reader.rejected == 0 and reader.lost == 0
