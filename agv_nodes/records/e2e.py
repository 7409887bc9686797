"""End-to-end protection of inter-processor records (modern extension, AUTOSAR E2E style).

Not in the 1983 thesis: its records carried no counter or CRC. This follows AUTOSAR E2E
Profile 1 (P01).

Byte 15 of a protected record is a sequence counter (+1 per publish, 255 wraps to 0) and byte 16
a CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, no reflection, xorout 0xFF) over the record's data_id
followed by bytes 1-15. A receiver rejects a bad CRC and classifies the counter step against
the last record it accepted (`delta` = counter - last, modulo 256):

- 0: REPEATED (not new data), rejected;
- 1..max_delta: OK or SOME_LOST (the gap is counted as lost), accepted;
- 256-max_delta..255: WRONG_SEQUENCE, the counter went back (a late or replayed record),
  rejected;
- anything between: WRONG_SEQUENCE, a jump (a foreign writer, a writer that restarted, or a
  long loss), rejected.

A rejected record never moves the reader's reference, so a forged or stray record cannot make
the next genuine record look out of sequence, nor open a window for later forged ones.

Resynchronisation, because a writer that restarts counts from 0 again: the reader moves its
reference only after `sync_records` (N, default 3) records that each jump forward out of the
window and each continue the one before (counter +1), all CRC-valid (a record with a bad CRC,
the wrong length or a malformed field is refused by the codec and never reaches the check). The
first of such a run is WRONG_SEQUENCE, the following ones SYNC (rejected, not acted on, counted
as resynchronising), and the Nth is accepted as INITIAL: the reader now follows that writer, and
the gap across the jump is not counted as lost. Runs are tracked by their last counter, several
at once, so records interleaved with a run (corrupt, repeated, stale or another run) neither
break it nor join it unless they continue it, and all runs are forgotten whenever a record is
accepted: a foreign writer interleaved with a live genuine one resynchronises the reader only if
N of its records arrive with no genuine record accepted in between. A record that went back
never starts or continues a run, so replaying the last max_delta records in order cannot move
the reader back. `resync()` forgets the reference at once (for a node that knows its writer
changed): the next valid record is then INITIAL.

What this cannot tell apart, as in P01: a CRC-8 is no signature, so N consecutive well-formed
records from any writer (or an ordered replay from more than max_delta records back) are a
writer, and a well-formed record inside the window is a genuine one.
"""

from __future__ import annotations

import enum

POLY = 0x1D
INIT = 0xFF
XOROUT = 0xFF


def _table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ POLY) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


CRC_TABLE = _table()  # CRC-8 SAE J1850 of each byte value (the generated fast paths use it too)


def crc8_sae_j1850(data: bytes | bytearray, init: int = INIT) -> int:
    """CRC-8/SAE-J1850 of `data` (check value of b'123456789' is 0x4B)."""
    crc = init
    for byte in data:
        crc = CRC_TABLE[crc ^ byte]
    return crc ^ XOROUT


def record_crc(data_id: int, first15: bytes | bytearray) -> int:
    """Return the byte-16 CRC of a protected record: over data_id then bytes 1-15."""
    crc = CRC_TABLE[INIT ^ data_id]  # = crc8_sae_j1850(bytes((data_id,)) + first15)
    for byte in first15:
        crc = CRC_TABLE[crc ^ byte]
    return crc ^ XOROUT


class Sequence(enum.Enum):
    """How a received counter relates to the previous accepted one (AUTOSAR E2E P01 terms)."""

    INITIAL = 'initial'  # first record, after resync() or the Nth of a run: accepted, syncs
    OK = 'ok'  # counter advanced by 1
    SOME_LOST = 'some_lost'  # advanced by 2..max_delta: accepted, the gap is counted
    REPEATED = 'repeated'  # same counter again: a replay or a duplicate, not new data
    WRONG_SEQUENCE = 'wrong_sequence'  # jumped too far or went back: rejected, state kept
    SYNC = 'sync'  # continues a run after a jump, not yet N long: rejected, not acted on


class SequenceCheck:
    """Classifies successive counters of one writer's records (see the module docstring)."""

    def __init__(self, max_delta: int = 15, sync_records: int = 3) -> None:
        if not 1 <= max_delta <= 127:
            raise ValueError(f'max_delta must be 1-127, not {max_delta}')
        if sync_records < 2:
            raise ValueError(f'sync_records must be at least 2, not {sync_records}')
        self.max_delta = max_delta
        self.sync_records = sync_records
        self.last: int | None = None  # counter of the last accepted record
        self.lost = 0  # records missed inside accepted gaps
        self.resyncs = 0  # runs that moved the reference
        self.runs: dict[int, int] = {}  # since the last accepted record: last counter -> length

    def check(self, counter: int) -> Sequence:
        """Classify `counter`; only an accepted verdict moves the reference.

        INITIAL, OK and SOME_LOST are accepted. A rejected verdict leaves `last` and `lost`
        as they were; a forward jump only starts or extends a run.
        """
        if self.last is None:
            return self._synchronise(counter)
        delta = (counter - self.last) & 0xFF
        if delta == 0:
            return Sequence.REPEATED
        if delta <= self.max_delta:
            self.last = counter
            self.runs.clear()  # the writer is in step: nothing seen meanwhile may build on
            if delta == 1:
                return Sequence.OK
            self.lost += delta - 1
            return Sequence.SOME_LOST
        if delta > 0xFF - self.max_delta:
            return Sequence.WRONG_SEQUENCE  # went back: late or replayed, never starts a run
        before = (counter - 1) & 0xFF
        if before not in self.runs:
            if counter in self.runs:
                return Sequence.REPEATED  # the same record of a run again
            self.runs[counter] = 1
            return Sequence.WRONG_SEQUENCE
        length = self.runs.pop(before) + 1
        if length >= self.sync_records:
            self.resyncs += 1
            return self._synchronise(counter)
        # a replay may join a run that has already passed this counter: the longer one stands
        self.runs[counter] = max(self.runs.get(counter, 0), length)
        return Sequence.SYNC

    def resync(self) -> None:
        """Forget the reference, for a writer known to have changed: the next is INITIAL."""
        self.last = None
        self.runs.clear()

    def _synchronise(self, counter: int) -> Sequence:
        self.last = counter
        self.runs.clear()
        return Sequence.INITIAL
