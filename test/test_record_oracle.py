"""The real `RecordReader` in lock step with the oracle written apart (test/record_oracle.py).

Hypothesis draws a writer's life on every record table: records sent in order, lost, repeated,
replayed, a writer that restarts anywhere (the reader told of it or not), runs of jumped
counters interleaved with the genuine stream, and corrupt ones (a flipped bit or byte anywhere,
a wrong length, a spare bit or an out-of-range value sealed with a good CRC, random bytes,
forged counters). The bytes are built by the oracle from msg_schemas/ with its own CRC, so the
codec under test makes none of them. After every record the reader must agree with the oracle:
taken with the same field values, or refused with the same reason; and its accepted, lost and
restart counts and its rejections by reason must stay equal to the oracle's.
"""

from __future__ import annotations

from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st
import pytest
from record_oracle import E2E, LENGTH, ReaderOracle, Table, compose, seal, tables

from agv_nodes.records.codec import codec
from agv_nodes.records.ports import RecordReader, RecordWriter

TABLES = tables()
NAMES = sorted(TABLES)
PROTECTED = [n for n in NAMES if TABLES[n].protected]


# -- what to send -----------------------------------------------------------------------------
def allowed_raws(table: Table) -> st.SearchStrategy[dict[str, int]]:
    """Raw values every column may hold, by the table."""
    def one(c):
        if c.names is not None:
            return st.sampled_from(sorted(c.names))
        valid = st.integers(c.lo, c.hi)
        return st.one_of(valid, st.sampled_from(sorted(c.special))) if c.special else valid
    return st.fixed_dictionaries({c.name: one(c) for c in table.columns})


def bad_raws(table: Table) -> list[tuple[str, int]]:
    """(column, raw value) pairs the table forbids: every one for narrow columns."""
    out = []
    for c in table.columns:
        full = range(-(1 << (c.width - 1)), 1 << (c.width - 1)) if c.signed \
            else range(1 << c.width)
        if c.wide:  # the edges and one past each
            full = [v for v in (full[0], c.lo - 1, c.hi + 1, full[-1]) if v in full]
        out += [(c.name, v) for v in full if not c.allowed(v)]
    return out


def spare_bits(table: Table) -> list[tuple[int, int]]:
    """(byte index, bit) of every bit no column claims, the E2E bytes aside."""
    last = E2E.counter_byte - 1 if table.protected else LENGTH
    return [(i, b) for i in range(last) for b in range(8) if not table.claimed[i] >> b & 1]


def steps(max_delta: int) -> st.SearchStrategy[tuple]:
    """One step of a writer's life; losses and forged counters often at the window's edges."""
    edges = st.sampled_from([max_delta - 1, max_delta, max_delta + 1])
    return st.one_of(
        st.tuples(st.just('send'), st.integers(1, 6)),
        st.tuples(st.just('lose'), st.one_of(st.integers(1, 40), edges)),
        st.tuples(st.just('near'), st.one_of(edges, edges.map(lambda d: -d))),
        STEPS)


STEPS = st.one_of(
    st.tuples(st.just('repeat'), st.integers(0, 9)),  # the k-th last record sent, again
    st.tuples(st.just('again'), st.integers(0, 3)),  # the k-th last item given, whatever it was
    st.tuples(st.just('restart'), st.integers(0, 255)),  # a new writer from this counter
    st.tuples(st.just('told'), st.integers(0, 255)),  # ... and the reader is told of it
    st.tuples(st.just('flip'), st.integers(0, 16 * 255 - 1)),  # byte and mask of a corruption
    st.tuples(st.just('length'), st.integers(0, 40).filter(lambda n: n != LENGTH)),
    st.tuples(st.just('spare'), st.integers(0, 10_000)),
    st.tuples(st.just('value'), st.integers(0, 10_000)),
    st.tuples(st.just('forge'), st.integers(0, 255)),  # well-formed, any counter
    st.tuples(st.just('noise'), st.binary(min_size=LENGTH, max_size=LENGTH)),
)


@st.composite
def history(draw, table: Table, integrity: str, max_delta: int = E2E.max_delta) -> list:
    """One reader's input: ('record', bytes) and ('resync',) items, in order."""
    payloads = draw(st.lists(allowed_raws(table), min_size=1, max_size=3))
    payloads = [compose(table, p) for p in payloads]
    sealed = table.protected and integrity == 'e2e'
    counter, sent, out = draw(st.integers(0, 255)), [], []

    def record(body: bytearray, at: int) -> bytes:
        return seal(table, body, at) if sealed else bytes(body)

    def new(body: bytearray | None = None) -> bytes:
        nonlocal counter
        data = record(body if body is not None else draw(st.sampled_from(payloads)), counter)
        counter = (counter + 1) % 256
        return data

    for op, n in draw(st.lists(steps(max_delta), min_size=1, max_size=40)) + [('send', 4)]:
        if op == 'send':
            for _ in range(n):
                sent.append(new())
                out.append(('record', sent[-1]))
        elif op == 'lose':
            counter = (counter + n) % 256
        elif op == 'repeat' and sent:
            out.append(('record', sent[-1 - n % len(sent)]))
        elif op == 'again' and out:
            out.append(out[-1 - n % len(out)])
        elif op in ('restart', 'told'):
            counter = n
            if op == 'told':
                out.append(('resync',))
        elif op == 'flip':
            data = bytearray(new())
            data[n // 255] ^= n % 255 + 1
            out.append(('record', bytes(data)))
        elif op == 'length':
            out.append(('record', (new() * 3)[:n]))
        elif op == 'spare' and spare_bits(table):
            i, bit = spare_bits(table)[n % len(spare_bits(table))]
            body = bytearray(draw(st.sampled_from(payloads)))
            body[i] |= 1 << bit
            out.append(('record', new(body)))
        elif op == 'value' and bad_raws(table):
            name, raw = bad_raws(table)[n % len(bad_raws(table))]
            body = compose(table, {**draw(allowed_raws(table)), name: raw})
            out.append(('record', new(body)))
        elif op == 'forge':
            out.append(('record', record(draw(st.sampled_from(payloads)), n)))
        elif op == 'near':  # n ahead of the last record sent (back, for n < 1)
            out.append(('record', record(draw(st.sampled_from(payloads)), counter - 1 + n)))
        elif op == 'noise':
            out.append(('record', n if not sealed or n[0] & 1 else seal(table, n, n[14])))
    return out


# -- the lock step ----------------------------------------------------------------------------
def lock_step(name: str, integrity: str, items: list, max_delta: int = E2E.max_delta,
              sync_records: int = E2E.sync_records) -> Counter:
    """Feed `items` to the reader and the oracle; fail at the first disagreement."""
    reader = RecordReader(codec()[name], integrity, max_delta, sync_records)
    oracle = ReaderOracle(TABLES[name], integrity, max_delta, sync_records)
    seen: Counter = Counter()
    for k, item in enumerate(items):
        if item[0] == 'resync':
            reader.resync()
            oracle.resync()
            continue
        data = item[1]
        before = reader.rejects.copy()
        got = reader.accept(data, k)
        want = oracle.judge(data)
        where = f'{name} ({integrity}) record {k} {data.hex()}: reader {got}, oracle {want}'
        seen[want.reason or 'accepted'] += 1
        if want.accepted:
            assert got == want.fields, where
            assert reader.restarted == (want.first and oracle.accepted > 1), where
        else:
            assert got is None, where
            assert reader.last_reason == want.reason, where
            assert reader.rejects - before == Counter({want.reason: 1}), where
        assert (reader.accepted, reader.lost, reader.restarts) == (
            oracle.accepted, oracle.lost, oracle.restarts), where
    assert reader.rejects == oracle.rejects
    return seen


@pytest.mark.timeout(300)
@pytest.mark.parametrize('name', NAMES)
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(data=st.data())
def test_the_reader_judges_every_record_as_the_oracle(name, data):
    integrity = data.draw(st.sampled_from(['e2e', 'none'])) if TABLES[name].protected \
        else 'e2e'
    lock_step(name, integrity, data.draw(history(TABLES[name], integrity)))


@pytest.mark.timeout(300)
@pytest.mark.parametrize('name', ['traction_command', 'route_status', 'comms_status'])
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(data=st.data(), max_delta=st.sampled_from([1, 2, 15, 16, 100, 127]),
       sync_records=st.integers(2, 5))
def test_the_reader_follows_the_counter_rules_for_any_window(name, data, max_delta,
                                                             sync_records):
    """Other windows and run lengths than the defaults (parameters of the reader)."""
    items = data.draw(history(TABLES[name], 'e2e', max_delta))
    lock_step(name, 'e2e', items, max_delta, sync_records)


@pytest.mark.timeout(300)
def test_the_draws_reach_every_verdict():
    """The histories above do exercise each rule: every verdict occurs in a fixed sample."""
    seen: Counter = Counter()

    @settings(max_examples=300, deadline=None, derandomize=True, database=None)
    @given(data=st.data())
    def sample(data):
        seen.update(lock_step('navigation_status', 'e2e',
                              data.draw(history(TABLES['navigation_status'], 'e2e'))))

    sample()
    assert set(seen) == {'accepted', 'wrong_length', 'bad_crc', 'spare_set', 'bad_value',
                         'repeated_counter', 'wrong_sequence', 'resyncing'}, seen


# -- the rules the docs state, one by one, on the real reader ---------------------------------
def stream(name: str, counters: list[int]) -> list:
    table = TABLES[name]
    body = compose(table, {c.name: min(c.names) if c.names is not None else
                           (0 if c.lo <= 0 <= c.hi else c.lo) for c in table.columns})
    return [('record', seal(table, body, c)) for c in counters]


@pytest.mark.timeout(60)
@pytest.mark.parametrize('counters, verdicts', [
    ([7, 7], ['accepted', 'repeated_counter']),
    ([7, 8, 8, 9], ['accepted', 'accepted', 'repeated_counter', 'accepted']),
    ([250, 9], ['accepted', 'accepted']),  # 15 ahead across the wrap: 14 lost
    ([250, 10], ['accepted', 'wrong_sequence']),  # 16 ahead: a jump
    ([7, 6], ['accepted', 'wrong_sequence']),  # went back
    ([7, 248, 249, 250], ['accepted', 'wrong_sequence', 'wrong_sequence', 'wrong_sequence']),
    ([7, 247, 247], ['accepted', 'wrong_sequence', 'repeated_counter']),  # 16 back: a jump
    ([7, 247, 248], ['accepted', 'wrong_sequence', 'wrong_sequence']),  # 15 back ends no run
    ([7, 100, 101, 102, 103], ['accepted', 'wrong_sequence', 'resyncing', 'accepted',
                               'accepted']),
    ([7, 100, 8, 101, 102], ['accepted', 'wrong_sequence', 'accepted', 'wrong_sequence',
                             'resyncing']),  # an accepted record ends the run
])
def test_the_counter_rules_of_docs_records_md(counters, verdicts):
    """Max 15 ahead (lost counted), repeated, went back, resynchronised by 3 in a row."""
    oracle = ReaderOracle(TABLES['traction_command'])
    got = [oracle.judge(item[1]).reason or 'accepted'
           for item in stream('traction_command', counters)]
    assert got == verdicts  # the oracle reads the docs so
    lock_step('traction_command', 'e2e', stream('traction_command', counters))


@pytest.mark.timeout(60)
@pytest.mark.parametrize('name', PROTECTED)
def test_what_the_writer_sends_the_oracle_takes(name):
    """The writer's records carry the counter (+1, wrapping) and the CRC of the docs."""
    writer = RecordWriter(codec()[name])
    oracle = ReaderOracle(TABLES[name])
    writer.counter = 250
    for k in range(10):
        raw = writer.pack({})
        verdict = oracle.judge(raw)
        assert verdict.accepted and raw[E2E.counter_byte - 1] == (250 + k) % 256, verdict
        assert verdict.fields == codec()[name].decode(raw)
