"""An oracle for the 16-byte records, written apart from the codec and the reader.

For any bytes and a reader's history it says what the reader must do: accept the record (and
with which field values, and how many records its counter says were lost), or reject it and
why (`wrong_length`, `bad_crc`, `spare_set`, `bad_value`, `repeated_counter`,
`wrong_sequence`, `resyncing`). It imports nothing of `agv_nodes`: the record tables are read
here from `msg_schemas/*.yaml` (field bytes, bits, encodings, min/max, special codes, enum
codes, the kind and data_id), and the E2E constants (where the counter and the CRC are, the
CRC-8 polynomial, init and xorout and its check value, the window of 15 and the 3 records that
resynchronise) are parsed from the prose of docs/records.md, so a change to either shows here
and not through the code under test. The CRC is computed bit by bit from the polynomial and
checked against the check value the docs give.

The rules, as docs/records.md and docs/architecture.md state them, and how this reads them
where they leave a choice (the docs cite AUTOSAR E2E Profile 1 "style" and records/e2e.py,
whose module docstring is the passage read for the sequence rules; no code of it is used):

1. Only 16 bytes are a record: any other length is `wrong_length`, before anything else.
2. Inter-processor records under `e2e`: byte 16 must be the CRC over data_id, then bytes
   1-15, or the record is `bad_crc`. Corrupt bytes say nothing about their fields, so the CRC
   is judged before any field (as in P01, where the CRC check comes first). Under `none`,
   bytes 15-16 are spare and must be 00H (`spare_set`); there is no sequence check.
   Hardware-side and ground-truth records use all 16 bytes and carry no protection.
3. "Every bit no field claims is spare and must be 0": `spare_set`. The docs give no order
   between a spare bit and a field's value; read here: spare bits first (they are judged per
   byte, before any field is taken apart), then the fields in the order the table lists them.
4. A field's value outside its min..max (the bits' whole range when the table gives none) and
   not one of its `special` codes, or an enum code the table does not list, is `bad_value`.
5. The sequence (e2e, inter-processor only), with delta = counter - reference mod 256, the
   reference being the counter of the last accepted record:
   - no reference yet (first record, or after the reader was told to resync): accepted;
   - delta 0: `repeated_counter`;
   - 1..max_delta: accepted; delta - 1 records counted lost;
   - 256 - max_delta..255: went back, `wrong_sequence`, and it never starts or continues a
     resynchronisation run;
   - anything between is a jump: rejected, the reference kept. "It resynchronises on the 3rd
     CRC-valid record of a run that jumps and continues itself": 3 records in all, the jump
     itself the first, each counter +1 on the one before;
     the first is `wrong_sequence`, the middle ones `resyncing`, the third accepted as the
     new writer's first record (no records counted lost across the jump). "In a row" is read
     as in counter order, not arrival: records that come in between (corrupt, stale,
     repeated, another run) neither break a run nor join it; every run is forgotten when a
     record is accepted, so a run must be completed with no record accepted meanwhile.
   - Which reason a duplicate within a run gets is not written in the docs. Read here as in
     P01, where the record that started a resynchronisation becomes the reference the next
     ones are compared with: each open run is such a candidate reference. A jump that
     continues an open run (its counter +1) is `resyncing` (or accepted when it makes the run
     3 long); one equal to the last counter of an open run is the same record again,
     `repeated_counter`; any other jump opens a run of its own, `wrong_sequence`. A run
     continued moves on (its old last counter is no longer an open end), and two runs that
     come to end on the same counter are one, as long as the longer of them.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
import re
from typing import Any

import yaml

REPO = Path(__file__).resolve().parent.parent
LENGTH = 16


@dataclass(frozen=True)
class Protection:
    """The E2E constants as docs/records.md states them."""

    counter_byte: int  # 1-16
    crc_byte: int
    poly: int
    init: int
    xorout: int
    check: int  # CRC of b'123456789'
    max_delta: int  # skipped counters counted as lost, up to this many
    sync_records: int  # records in a row that resynchronise


def _hex(text: str) -> int:
    return int(text.rstrip('Hh'), 16)


def protection_from_docs(path: Path = REPO / 'docs' / 'records.md') -> Protection:
    """Parse the E2E paragraph of docs/records.md (an AssertionError if it says otherwise)."""
    text = ' '.join(path.read_text().split())
    m = re.search(r'byte (\d+) is a sequence counter .*? and byte (\d+) a CRC-8/SAE-J1850 '
                  r'\(poly (\w+), init (\w+), no reflection, xorout (\w+); '
                  r'check\("123456789"\) = (\w+)\) over the record\'s `data_id` followed by '
                  r'bytes 1-(\d+)\.', text)
    assert m, f'{path}: the E2E paragraph no longer reads as this oracle expects'
    counter, crc = int(m[1]), int(m[2])
    assert int(m[7]) == counter and crc == LENGTH, (m[0], 'the CRC covers bytes 1 to counter')
    lost = re.search(r'counts skipped counters \(up to (\d+)\) as lost\. A jump of more than '
                     r'(\d+) is rejected', text)
    sync = re.search(r'resynchronises on the (\d+)(?:st|nd|rd|th)\s+CRC-valid record of a run '
                     r'that jumps and continues itself', text)
    assert lost and sync and lost[1] == lost[2], f'{path}: the counter rules no longer parse'
    return Protection(counter, crc, _hex(m[3]), _hex(m[4]), _hex(m[5]), _hex(m[6]),
                      int(lost[1]), int(sync[1]))


def crc8(data: bytes, poly: int, init: int, xorout: int) -> int:
    """CRC-8, MSB first, no reflection: bit by bit, as the polynomial defines it."""
    crc = init
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ poly) if crc & 0x80 else crc << 1
            crc &= 0xFF
    return crc ^ xorout


E2E = protection_from_docs()
assert crc8(b'123456789', E2E.poly, E2E.init, E2E.xorout) == E2E.check, 'CRC-8 of the docs'


def record_crc(data_id: int, data: bytes) -> int:
    """Return the CRC byte of a protected record: over data_id, then bytes 1 to the counter."""
    return crc8(bytes([data_id]) + bytes(data[:E2E.counter_byte]), E2E.poly, E2E.init,
                E2E.xorout)


# -- the tables -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Column:
    """One field as the table gives it: where its bits are and which raw values it may take."""

    name: str
    index: int  # first byte, from 0
    wide: bool  # two bytes, little-endian
    lo_bit: int
    width: int
    signed: bool
    lo: int
    hi: int
    special: frozenset[int]
    names: dict[int, str] | None  # enum codes -> names

    def raw(self, data: bytes) -> int:
        """Return the field's value in `data`, sign-extended where the encoding is signed."""
        if self.wide:
            value = data[self.index] | data[self.index + 1] << 8
        else:
            value = (data[self.index] >> self.lo_bit) & ((1 << self.width) - 1)
        if self.signed and value >> (self.width - 1):
            value -= 1 << self.width
        return value

    def allowed(self, value: int) -> bool:
        """Say whether the table lets this field hold `value`."""
        if self.names is not None:
            return value in self.names
        return self.lo <= value <= self.hi or value in self.special

    def shown(self, value: int) -> Any:
        """Return the value as a reader hands it on: an enum's name, else the integer."""
        return self.names[value] if self.names is not None else value


def _bits(spec: Any) -> tuple[int, int]:
    lo, _, hi = str(spec).partition('-')
    a, b = int(lo), int(hi or lo)
    return min(a, b), max(a, b)


@dataclass(frozen=True)
class Table:
    """One record's table (msg_schemas/<name>.yaml)."""

    name: str
    data_id: int
    kind: str
    columns: tuple[Column, ...]
    claimed: tuple[int, ...]  # per byte: the bits some field claims

    @property
    def protected(self) -> bool:
        """Inter-processor records carry the counter and CRC."""
        return self.kind == 'inter_processor'


def read_table(path: Path) -> Table:
    """Read one schema file into a Table."""
    doc = yaml.safe_load(path.read_text())
    columns, claimed = [], [0] * LENGTH
    for spec in doc['fields']:
        first, last = _bits(spec['byte'])
        enc = spec['encoding']
        wide = last > first
        lo_bit, hi_bit = (0, 7) if wide else _bits(spec.get('bits', '0-7'))
        width = 16 if wide else hi_bit - lo_bit + 1
        signed = enc in ('twos_complement', 's16le')
        full = (-(1 << (width - 1)), (1 << (width - 1)) - 1) if signed else (0, (1 << width) - 1)
        names = {code: name for name, code in spec['values'].items()} if enc == 'enum' else None
        columns.append(Column(spec['name'], first - 1, wide, lo_bit, width, signed,
                              spec.get('min', full[0]), spec.get('max', full[1]),
                              frozenset(spec.get('special') or {}), names))
        for i in range(first - 1, last):
            claimed[i] |= 0xFF if wide else ((1 << width) - 1) << lo_bit
    return Table(doc['record'], doc['data_id'], doc['kind'], tuple(columns), tuple(claimed))


def tables(folder: Path = REPO / 'msg_schemas') -> dict[str, Table]:
    """Every record table, by name."""
    return {t.name: t for t in map(read_table, sorted(folder.glob('*.yaml')))}


# -- the verdicts -----------------------------------------------------------------------------
@dataclass(frozen=True)
class Verdict:
    """What a reader must do with one record."""

    reason: str = ''  # '' = accepted
    fields: dict[str, Any] | None = None  # the accepted record's values
    lost: int = 0  # records its counter says were missed
    first: bool = False  # taken as a writer's first record (no reference, or a resync)

    @property
    def accepted(self) -> bool:
        """True when the record is taken."""
        return not self.reason


def judge_bytes(table: Table, data: bytes, integrity: str = 'e2e') -> Verdict:
    """Judge the bytes alone (rules 1-4): a reason, or the field values."""
    if len(data) != LENGTH:
        return Verdict('wrong_length')
    data = bytes(data)
    checked = LENGTH
    if table.protected:
        checked = E2E.counter_byte - 1
        if integrity == 'e2e':
            if data[E2E.crc_byte - 1] != record_crc(table.data_id, data):
                return Verdict('bad_crc')
        elif data[E2E.counter_byte - 1] or data[E2E.crc_byte - 1]:
            return Verdict('spare_set')
    if any(data[i] & ~table.claimed[i] & 0xFF for i in range(checked)):
        return Verdict('spare_set')
    values = {}
    for column in table.columns:
        raw = column.raw(data)
        if not column.allowed(raw):
            return Verdict('bad_value')
        values[column.name] = column.shown(raw)
    return Verdict(fields=values)


@dataclass
class Run:
    """Records that jumped out of the window, each counter +1 on the one before."""

    last: int
    length: int


@dataclass
class ReaderOracle:
    """What one reader of `table` must do with each record it is given, in order."""

    table: Table
    integrity: str = 'e2e'
    max_delta: int = E2E.max_delta
    sync_records: int = E2E.sync_records
    reference: int | None = None  # counter of the last accepted record
    runs: list[Run] = field(default_factory=list)
    accepted: int = 0
    lost: int = 0
    restarts: int = 0  # writers' first records taken after an earlier writer was followed
    rejects: Counter = field(default_factory=Counter)
    told: bool = False  # resync() since the last accepted record

    @property
    def sequenced(self) -> bool:
        """Whether records are judged by their counter."""
        return self.table.protected and self.integrity == 'e2e'

    def resync(self) -> None:
        """Tell the reader its writer is new: the next valid record is taken whatever."""
        self.reference, self.runs, self.told = None, [], True

    def judge(self, data: bytes) -> Verdict:
        """Judge `data` and update the history as the reader must."""
        verdict = judge_bytes(self.table, data, self.integrity)
        if verdict.accepted and self.sequenced:
            reason, lost, first = self._sequence(data[E2E.counter_byte - 1])
            verdict = Verdict(reason, None if reason else verdict.fields, lost, first)
        elif verdict.accepted:
            verdict = Verdict(fields=verdict.fields, first=self.told)
        if not verdict.accepted:
            self.rejects[verdict.reason] += 1
            return verdict
        self.restarts += verdict.first and self.accepted > 0
        self.accepted += 1
        self.lost += verdict.lost
        self.runs, self.told = [], False
        return verdict

    def peek(self, data: bytes) -> Verdict:
        """Return the verdict `judge` would give, leaving the history as it is."""
        trial = replace(self, runs=[Run(r.last, r.length) for r in self.runs],
                        rejects=Counter())
        return trial.judge(data)

    def _sequence(self, counter: int) -> tuple[str, int, bool]:
        """(reason or '', records lost, first record of a writer) for a CRC-valid record."""
        if self.reference is None:
            self.reference = counter
            return '', 0, True
        delta = (counter - self.reference) % 256
        if delta == 0:
            return 'repeated_counter', 0, False
        if delta <= self.max_delta:
            self.reference = counter
            return '', delta - 1, False
        if delta >= 256 - self.max_delta:
            return 'wrong_sequence', 0, False
        behind = [r for r in self.runs if r.last == (counter - 1) % 256]
        if behind:
            length = max(r.length for r in behind) + 1
            if length >= self.sync_records:
                self.reference = counter
                return '', 0, True
            same = [r for r in self.runs if r.last == counter]
            self.runs = [r for r in self.runs if r not in behind and r not in same]
            self.runs.append(Run(counter, max([length] + [r.length for r in same])))
            return 'resyncing', 0, False
        if any(r.last == counter for r in self.runs):
            return 'repeated_counter', 0, False
        self.runs.append(Run(counter, 1))
        return 'wrong_sequence', 0, False


def seal(table: Table, data: bytes | bytearray, counter: int) -> bytes:
    """Return `data` (bytes 1-14 kept) with `counter` and the CRC it needs."""
    out = bytearray(data[:LENGTH].ljust(LENGTH, b'\0'))
    out[E2E.counter_byte - 1] = counter & 0xFF
    out[E2E.crc_byte - 1] = record_crc(table.data_id, out)
    return bytes(out)


def compose(table: Table, raws: dict[str, int]) -> bytearray:
    """Bytes holding each column's raw value (two's complement where signed), the rest 0."""
    out = bytearray(LENGTH)
    for column in table.columns:
        value = raws[column.name] & ((1 << column.width) - 1)
        if column.wide:
            out[column.index], out[column.index + 1] = value & 0xFF, value >> 8
        else:
            out[column.index] |= value << column.lo_bit
    return out
