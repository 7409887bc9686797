"""Record ports: the ROS-free ends of a record topic, shared by the nodes and the harness.

A `RecordWriter` packs a core's field dict into 16 bytes (advancing the E2E counter); a
`RecordReader` validates what arrives and keeps the last good record, its age, and a count of
every rejection by reason, so `/diagnostics` can show "the 32 bytes" (thesis 8.2.2) and rejects.
A rejected record changes nothing but the rejection counts (and, for a counter jump, the
resynchronisation runs of records/e2e.py): the last good record, its age and the sequence
reference stay as they were.

`WriterCheck` decides who may write a topic: the one DDS endpoint the ROS graph names as the
schema's writer node (or the writer a reader is told to take instead: a node, or an endpoint GID
for a driver that is no ROS node). Records from any other endpoint are rejected as
`foreign_writer`: counted and shown like every other reason, never acted on, and
(agv_nodes/ros_ports.py) never passed to a core's rejection budget. Two live endpoints that both
write as the named writer are a fault, `duplicate_writer`: every record of either is rejected and
the reader's node is told, so that it stops the truck. `SwitchInput` applies the same check to a
stop switch (hw/radio_stop, hw/bumper): a foreign `true` still stops, a foreign `false` never
releases.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from agv_nodes.records.e2e import Sequence, SequenceCheck
from agv_nodes.records.errors import RecordError, Reject
from agv_nodes.records.schema import COUNTER_BYTE, RecordSchema
from agv_nodes.records.writer_check import (
    DUPLICATE_WRITER,
    FOREIGN_WRITER,
    GID_PREFIX,
    UNKNOWN_NODE,
    CheckedInput,
    SwitchInput,
    WriterCheck,
    gid_writer,
    node_name,
)

__all__ = ['CORRUPT', 'DUPLICATE_WRITER', 'FOREIGN_WRITER', 'GID_PREFIX', 'UNKNOWN_NODE',
           'CheckedInput', 'RecordReader', 'RecordWriter', 'SwitchInput', 'WriterCheck',
           'gid_writer',
           'inputs_report', 'node_name', 'CountedInput']


class RecordWriter:
    """Packs records of one schema for one writer."""

    def __init__(self, schema: RecordSchema, integrity: str = 'e2e') -> None:
        self.schema = schema
        self.integrity = integrity
        self.counter = 0
        self.last_raw: bytes | None = None
        self.sent = 0
        paths = schema.port_paths(integrity)
        self._seal = paths[0] if paths is not None else None

    @property
    def last_fields(self) -> dict[str, Any] | None:
        """The fields of the last record sent, as its readers decode them (None: none yet).

        Decoded when asked (a diagnostics page a second), not kept on every publish.
        """
        if self.last_raw is None:
            return None
        return self.schema.decode(self.last_raw, integrity=self.integrity)

    def pack(self, fields: Mapping[str, Any]) -> bytes:
        """16 bytes for `fields`; each call is one publish (the counter advances)."""
        # None from the fast path: something the general path must judge (or fill in)
        if self._seal is None or (raw := self._seal(fields, self.counter)) is None:
            raw = self.schema.encode(fields, integrity=self.integrity, counter=self.counter)
        self.counter = (self.counter + 1) & 0xFF
        self.last_raw = raw
        self.sent += 1
        return raw


# Rejections that mean the bytes themselves are corrupt (as opposed to stale or out of order).
CORRUPT = frozenset(r.value for r in (Reject.BAD_CRC, Reject.WRONG_LENGTH, Reject.SPARE_SET,
                                      Reject.BAD_VALUE))


class RecordReader:
    """Validates received records of one schema; never lets a bad one through.

    `schema` and `integrity` are fixed at construction (the fast paths are chosen for them).
    """

    def __init__(self, schema: RecordSchema, integrity: str = 'e2e',
                 max_delta: int = 15, sync_records: int = 3) -> None:
        self.schema = schema
        self.integrity = integrity
        self.sequence = SequenceCheck(max_delta, sync_records)
        self.fields: dict[str, Any] | None = None  # last accepted record
        self.raw: bytes | None = None  # its 16 bytes
        self.stamp_ns: int | None = None  # when it was accepted
        self.accepted = 0
        self.restarts = 0  # times the reader took up a writer anew after following one
        self.restarted = False  # the record just accepted is the first of a new writer
        self._new_writer = False  # resync() was told the writer changed
        self.rejects: Counter[str] = Counter()
        self.last_error: str = ''
        self.last_reason: str = ''  # key of the last rejection (bad_crc, spare_set, ...)
        self.duplicate: str = ''  # while two endpoints both write as the named writer: who
        self.waiting: str = ''  # while the named writer has not been heard for too long: who
        paths = schema.port_paths(integrity)
        # bytes -> their fields, or None for anything `decode`'s general path must judge
        self.fast_decode: Callable[[Any], dict[str, Any] | None] | None = \
            paths[1] if paths is not None else None
        self._e2e = schema.protected and integrity == 'e2e'

    @property
    def rejected(self) -> int:
        """Total records rejected."""
        return sum(self.rejects.values())

    def accept(self, data: bytes | bytearray, now_ns: int) -> dict[str, Any] | None:
        """Decode `data`; return its fields, or None (and count why) when it is rejected."""
        try:
            fields = self.decode(data)
        except RecordError as exc:
            self._reject(exc.code.value, str(exc))
            return None
        return self.take(data, fields, now_ns)

    def decode(self, data: bytes | bytearray) -> dict[str, Any]:
        """Return the fields of `data` (RecordError if the codec refuses it; nothing counted).

        Only the bytes are judged, as every reader of this schema and integrity would judge
        them: `take` does the rest of `accept`.
        """
        # None from the fast path: something the general path must judge and name
        if self.fast_decode is not None and (fields := self.fast_decode(data)) is not None:
            return fields
        return self.schema.decode(data, integrity=self.integrity)

    def take(self, data: bytes | bytearray, fields: dict[str, Any],
             now_ns: int) -> dict[str, Any] | None:
        """Judge the sequence of a record the codec took (`fields`, as `decode` gave them).

        Return `fields`, or None (and count why) when it is rejected. A reader of the same
        schema and integrity may be given another reader's decoding of the same bytes (a copy
        of it: the dict becomes this reader's `fields`).
        """
        initial = False
        if self._e2e:
            counter = data[COUNTER_BYTE - 1]
            sequence = self.sequence
            last = sequence.last
            # the usual step, +1 with no run since the last accepted record: OK (e2e.py)
            if last is not None and counter == (last + 1) & 0xFF and not sequence.runs:
                sequence.last = counter
            else:
                verdict = sequence.check(counter)
                if verdict is Sequence.REPEATED:
                    self._reject('repeated_counter', f'{self.schema.name}: repeated counter '
                                 f'{counter} (not new data)')
                    return None
                if verdict is Sequence.WRONG_SEQUENCE:
                    self._reject('wrong_sequence', f'{self.schema.name}: counter {counter} out '
                                 f'of sequence (last accepted {self.sequence.last})')
                    return None
                if verdict is Sequence.SYNC:
                    self._reject('resyncing', f'{self.schema.name}: counter {counter} '
                                 'continues a run after a jump (resynchronising after '
                                 f'{self.sequence.sync_records}, not acted on)')
                    return None
                initial = verdict is Sequence.INITIAL
        # a writer taken up anew after one was followed: it restarted (or was replaced), and
        # whatever state its reader's node built on the old one is gone
        if initial or self._new_writer:
            self.restarted = restarted = self.accepted > 0
            self.restarts += restarted
            self._new_writer = False
        else:  # the usual record
            self.restarted = False
        self.fields = fields
        self.raw = data if type(data) is bytes else bytes(data)
        self.stamp_ns = now_ns
        self.accepted += 1
        return fields

    def identity(self) -> str:
        """Say who this reader takes records from ('' where there are no endpoints)."""
        return ''

    def resync(self) -> None:
        """Accept the next valid record whatever its counter (its writer is known to be new)."""
        self.sequence.resync()
        self._new_writer = True

    def age_s(self, now_ns: int) -> float:
        """Seconds since the last accepted record (inf if none yet)."""
        return float('inf') if self.stamp_ns is None else (now_ns - self.stamp_ns) * 1e-9

    @property
    def lost(self) -> int:
        """Records missed in accepted counter gaps."""
        return self.sequence.lost

    def _reject(self, reason: str, text: str) -> None:
        self.rejects[reason] += 1
        self.last_error = text
        self.last_reason = reason


class CountedInput(Protocol):
    """What inputs_report reads of an input: a RecordReader, or a CheckedInput's stream."""

    accepted: int
    rejects: Counter[str]
    last_error: str
    duplicate: str  # while two endpoints both write as the named writer: who

    @property
    def rejected(self) -> int:
        """Return the records refused."""
        ...

    @property
    def lost(self) -> int:
        """Return the records missed in counter gaps (0 where there are no counters)."""
        ...

    def age_s(self, now_ns: int) -> float:
        """Return the seconds since the last one acted on (inf if none yet)."""
        ...

    def identity(self) -> str:
        """Say whose input this is (its /diagnostics `writer` value)."""
        ...


def inputs_report(readers: Mapping[str, CountedInput], rejected_before: int = 0,
                  now_ns: int | None = None,
                  health: tuple[int, str] | None = None) -> tuple[int, str, dict[str, str]]:
    """One node's record inputs for /diagnostics: (level 0 OK / 1 WARN / 2 ERROR, message, values).

    WARN while records are being rejected (more than `rejected_before` in all), so a foreign or
    faulty writer shows at once, or while an input waits for its named writer (`waiting`); the
    counts themselves never reset. ERROR while two endpoints both write as one input's named
    writer (`duplicate`, naming both). `health` is the node's own verdict (e.g. traction's trip
    relay), which comes first in the message.
    """
    values: dict[str, str] = {}
    total = 0
    by_reason: Counter[str] = Counter()
    for name, reader in sorted(readers.items()):
        total += reader.rejected
        by_reason.update(reader.rejects)
        values[f'{name} accepted'] = str(reader.accepted)
        values[f'{name} rejected'] = str(reader.rejected)
        values[f'{name} rejects by reason'] = ', '.join(
            f'{k}={v}' for k, v in sorted(reader.rejects.items())) or 'none'
        values[f'{name} lost (counter gaps)'] = str(reader.lost)
        if now_ns is not None:
            age = reader.age_s(now_ns)
            values[f'{name} age (s)'] = 'never' if age == float('inf') else f'{age:.3f}'
        if reader.identity():
            values[f'{name} writer'] = reader.identity()
        if reader.last_error:
            values[f'{name} last rejection'] = reader.last_error
    values['rejected'] = str(total)
    reasons = ', '.join(f'{k}={v}' for k, v in sorted(by_reason.items()))
    if total > rejected_before:
        level, message = 1, (f'{total - rejected_before} records rejected recently ({total} '
                             f'in all: {reasons})')
    else:
        level, message = 0, f'inputs valid ({total} rejected in all' \
                            f'{": " + reasons if total else ""})'
    waits = [text for reader in readers.values() if (text := getattr(reader, 'waiting', ''))]
    if waits:
        level, message = max(level, 1), '; '.join([*waits, message])
    duplicates = [reader.duplicate for _name, reader in sorted(readers.items())
                  if reader.duplicate]
    if duplicates:
        level, message = 2, '; '.join([*(f'duplicate writer: {d}' for d in duplicates),
                                       message])
    if health is not None and health[1]:
        level, message = max(level, health[0]), f'{health[1]}; {message}'
    return level, message, values
