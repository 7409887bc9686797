"""End-to-end protection of inter-processor records (modern extension, AUTOSAR E2E style).

Byte 15 of a protected record is a sequence counter (+1 per publish, 255 wraps to 0) and byte 16
a CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, no reflection, xorout 0xFF) over the record's data_id
followed by bytes 1-15. A receiver rejects a bad CRC and classifies the counter step.
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


_TABLE = _table()


def crc8_sae_j1850(data: bytes | bytearray, init: int = INIT) -> int:
    """CRC-8/SAE-J1850 of `data` (check value of b'123456789' is 0x4B)."""
    crc = init
    for byte in data:
        crc = _TABLE[crc ^ byte]
    return crc ^ XOROUT


def record_crc(data_id: int, first15: bytes | bytearray) -> int:
    """Return the byte-16 CRC of a protected record: over data_id then bytes 1-15."""
    crc = _TABLE[INIT ^ data_id]  # = crc8_sae_j1850(bytes((data_id,)) + first15)
    for byte in first15:
        crc = _TABLE[crc ^ byte]
    return crc ^ XOROUT


class Sequence(enum.Enum):
    """How a received counter relates to the previous accepted one (AUTOSAR E2E P01 terms)."""

    INITIAL = 'initial'  # first record seen: accepted, synchronises
    OK = 'ok'  # counter advanced by 1
    SOME_LOST = 'some_lost'  # advanced by 2..max_delta: accepted, the gap is counted
    REPEATED = 'repeated'  # same counter again: a replay or a duplicate, not new data
    WRONG_SEQUENCE = 'wrong_sequence'  # jumped too far (or went back): rejected, resynchronises


class SequenceCheck:
    """Classifies successive counters of one writer's records."""

    def __init__(self, max_delta: int = 15) -> None:
        self.max_delta = max_delta
        self.last: int | None = None
        self.lost = 0  # records missed inside accepted gaps

    def check(self, counter: int) -> Sequence:
        """Classify `counter` and update the state; the caller acts on the verdict."""
        if self.last is None:
            self.last = counter
            return Sequence.INITIAL
        delta = (counter - self.last) & 0xFF
        if delta == 0:
            return Sequence.REPEATED
        self.last = counter  # resynchronise on every new value, accepted or not
        if delta == 1:
            return Sequence.OK
        if delta <= self.max_delta:
            self.lost += delta - 1
            return Sequence.SOME_LOST
        return Sequence.WRONG_SEQUENCE
