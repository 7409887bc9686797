"""The model of one 16-byte record: its fields and how they pack into and out of bytes.

Byte numbers follow the thesis (1-16). Inter-processor records keep bytes 15-16 for end-to-end
protection (`integrity='e2e'`: counter and CRC-8, see e2e.py) or require them to be 00H
(`integrity='none'`: a legacy peer sending plain thesis records). Hardware-side records use all 16
bytes and carry no protection. Every bit that no field claims is spare and must be 0. Each schema
also generates straight-line fast paths once (records/fast_paths.py).
"""

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
import functools
from pathlib import Path
from typing import Any

from agv_nodes.records.compiled_paths import compiled_port_paths
from agv_nodes.records.e2e import record_crc
from agv_nodes.records.errors import RecordError, Reject
from agv_nodes.records.fast_paths import compile_fast_paths, compile_port_paths

RECORD_LENGTH = 16
COUNTER_BYTE = 15
CRC_BYTE = 16
INTEGRITY_MODES = ('e2e', 'none')
KINDS = ('inter_processor', 'hardware', 'ground_truth')
ENCODINGS = ('flag', 'unsigned', 'twos_complement', 'enum', 'u16le', 's16le')
QOS_CLASSES = ('record', 'stream')


@dataclass(frozen=True)
class Field:
    """One field of a record: where it lives, how it is coded, what it means."""

    name: str
    byte: int  # first byte, thesis numbering 1-16
    n_bytes: int
    lo_bit: int
    hi_bit: int
    encoding: str
    lo: int  # smallest valid raw value (outside `special`)
    hi: int
    special: Mapping[int, str]
    values: Mapping[str, int]  # enum names -> codes
    default: Any
    units: str = ''
    zero: str = ''
    one: str = ''
    thesis: str = ''
    names: Mapping[int, str] = field(default_factory=dict)  # enum codes -> names

    @property
    def width(self) -> int:
        """Width in bits."""
        return 8 * self.n_bytes if self.n_bytes > 1 else self.hi_bit - self.lo_bit + 1

    @property
    def mask(self) -> int:
        """Mask of the field's bits within its (single) byte."""
        return ((1 << self.width) - 1) << self.lo_bit

    def bits_text(self) -> str:
        """Bit range as the docs print it."""
        if self.n_bytes > 1:
            return '0-7'
        return str(self.lo_bit) if self.lo_bit == self.hi_bit else f'{self.hi_bit}-{self.lo_bit}'

    def bytes_text(self) -> str:
        """Byte range as the docs print it."""
        last = self.byte + self.n_bytes - 1
        return str(self.byte) if last == self.byte else f'{self.byte}-{last}'

    def valid(self, raw: int) -> bool:
        """Return True when `raw` is a value this field may carry."""
        if self.encoding == 'enum':
            return raw in self.names
        return self.lo <= raw <= self.hi or raw in self.special


@dataclass(frozen=True)
class RecordSchema:
    """A 16-byte record: identity, routing, and its fields."""

    name: str
    data_id: int
    kind: str
    topic: str
    writer: str
    readers: tuple[str, ...]
    period_ms: float
    qos: str
    thesis: str
    summary: str
    fields: tuple[Field, ...]
    path: Path
    used: tuple[int, ...] = ()  # per byte (index 0 = byte 1): mask of bits fields claim

    @property
    def protected(self) -> bool:
        """Inter-processor records carry the E2E counter and CRC in bytes 15-16."""
        return self.kind == 'inter_processor'

    def field(self, name: str) -> Field:
        """Return the field called `name` (RecordError if there is none)."""
        for f in self.fields:
            if f.name == name:
                return f
        raise RecordError(self.name, 'no such field', code=Reject.UNKNOWN_FIELD, field=name)

    def defaults(self) -> dict[str, Any]:
        """Every field at its documented default."""
        return {f.name: f.default for f in self.fields}

    def describe(self, fields: Mapping[str, Any]) -> dict[str, str]:
        """Say what each decoded value means, in words (for displays and `agv-records decode`)."""
        out = {}
        for f in self.fields:
            value = fields.get(f.name, f.default)
            if f.encoding == 'flag':
                out[f.name] = f.one if value else f.zero
            elif isinstance(value, int) and value in f.special:
                out[f.name] = f.special[value]
            else:
                out[f.name] = f'{value} {f.units}'.strip() if f.encoding != 'enum' else value
        return out

    # -- encode / decode plans -------------------------------------------------------------
    # The codec runs about 2,000 times per simulated second in the lock-step harness and on
    # every record a node sends or takes: what each field needs is worked out once per schema
    # (a frozen dataclass still has an instance __dict__ for cached_property).
    @functools.cached_property
    def _plan(self) -> tuple[tuple, ...]:
        return tuple((f, f.name, f.byte - 1, f.n_bytes == 2, f.lo_bit, (1 << f.width) - 1,
                      f.width, f.encoding, f.lo, f.hi, frozenset(f.special), f.names, f.values)
                     for f in self.fields)

    @functools.cached_property
    def _names(self) -> frozenset[str]:
        return frozenset(f.name for f in self.fields)

    @functools.cached_property
    def _spare_masks(self) -> tuple[int, int]:
        """Bits no field claims, as one integer over bytes 1-14 and over bytes 1-16."""
        spare = bytes(~u & 0xFF for u in self.used)
        return int.from_bytes(spare[:14], 'big'), int.from_bytes(spare, 'big')

    # -- encode ---------------------------------------------------------------------------
    def encode(self, values: Mapping[str, Any] | None = None, *, integrity: str = 'e2e',
               counter: int = 0) -> bytes:
        """Pack `values` (missing fields take their defaults) into 16 bytes."""
        values = {} if values is None else values
        if not self._names.issuperset(values):
            raise RecordError(self.name, 'no such field', code=Reject.UNKNOWN_FIELD,
                              field=sorted(set(values) - self._names)[0])
        _check_integrity(self.name, integrity)
        # None from the fast path: something the general path must judge
        out = self._compiled[0](values) or self._encode_fields(values)
        if self.protected and integrity == 'e2e':
            if not 0 <= counter <= 255:
                raise RecordError(self.name, 'e2e counter must be 0-255', code=Reject.BAD_VALUE,
                                  byte=COUNTER_BYTE, field='e2e_counter', value=counter)
            out[COUNTER_BYTE - 1] = counter
            out[CRC_BYTE - 1] = record_crc(self.data_id, out[:15])
        return bytes(out)

    def _encode_fields(self, values: Mapping[str, Any]) -> bytearray:
        """Bytes 1-16 for `values`, field by field (the reference; raises for a bad value)."""
        out = bytearray(RECORD_LENGTH)
        get = values.get
        for f, name, index, two, lo_bit, mask, _w, enc, lo, hi, special, _n, codes in self._plan:
            value = get(name, f.default)
            if enc == 'enum':
                raw = codes[value] if type(value) is str and value in codes \
                    else self._to_raw(f, value)
            elif type(value) is int and (lo <= value <= hi or value in special):
                raw = value
            else:
                raw = self._to_raw(f, value)  # bools, names of special values, errors
            if two:
                raw &= 0xFFFF
                out[index] = raw & 0xFF
                out[index + 1] = raw >> 8
            else:
                out[index] |= (raw & mask) << lo_bit
        return out

    def _to_raw(self, f: Field, value: Any) -> int:
        if f.encoding == 'enum' and isinstance(value, str):
            if value not in f.values:
                raise RecordError(self.name, f'unknown enum name (one of {list(f.values)})',
                                  code=Reject.BAD_VALUE, byte=f.byte, field=f.name, value=value)
            return f.values[value]
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, int):
            if isinstance(value, str) and value in f.special.values():
                return next(k for k, v in f.special.items() if v == value)
            raise RecordError(self.name, 'value must be an integer', code=Reject.BAD_VALUE,
                              byte=f.byte, field=f.name, value=value)
        if not f.valid(value):
            raise RecordError(self.name, f'value out of range {self._range_text(f)}',
                              code=Reject.BAD_VALUE, byte=f.byte, field=f.name, value=value)
        return value

    @staticmethod
    def _range_text(f: Field) -> str:
        if f.encoding == 'enum':
            return str(sorted(f.names))
        text = f'{f.lo}..{f.hi}'
        if f.special:
            text += ' or ' + ', '.join(f'{k:02X}H' for k in f.special)
        return text

    # -- decode ---------------------------------------------------------------------------
    def decode(self, data: bytes | bytearray | Iterable[int], *,
               integrity: str = 'e2e') -> dict[str, Any]:
        """Unpack and validate 16 bytes; raise RecordError for anything that does not fit."""
        if type(data) is not bytes:
            data = bytes(data)
        if len(data) != RECORD_LENGTH:
            raise RecordError(self.name, f'length {len(data)}, expected {RECORD_LENGTH} bytes',
                              code=Reject.WRONG_LENGTH)
        _check_integrity(self.name, integrity)
        check_spare = RECORD_LENGTH
        if self.protected:
            check_spare = 14
            if integrity == 'e2e':
                crc = record_crc(self.data_id, data[:15])
                if data[CRC_BYTE - 1] != crc:
                    raise RecordError(self.name, f'bad CRC, expected {crc:02X}H',
                                      code=Reject.BAD_CRC, byte=CRC_BYTE, field='e2e_crc',
                                      value=data[CRC_BYTE - 1])
            else:
                for byte in (COUNTER_BYTE, CRC_BYTE):
                    if data[byte - 1]:
                        raise RecordError(self.name, 'spare byte set (integrity none: 00H)',
                                          code=Reject.SPARE_SET, byte=byte,
                                          value=data[byte - 1])
        spare = self._spare_masks[0 if check_spare == 14 else 1]
        if int.from_bytes(data[:check_spare], 'big') & spare:
            for i in range(check_spare):
                if stray := data[i] & ~self.used[i] & 0xFF:
                    raise RecordError(self.name, f'spare bits set (mask {stray:02X}H), must be '
                                      '0', code=Reject.SPARE_SET, byte=i + 1, value=data[i])
        out = self._compiled[1](data)  # None: a value the general path must name
        return out if out is not None else self._decode_fields(data)

    def _decode_fields(self, data: bytes) -> dict[str, Any]:
        """Decode checked bytes field by field (the reference; raises for a bad value)."""
        out: dict[str, Any] = {}
        for f, name, index, two, lo_bit, mask, width, enc, lo, hi, special, names, _c \
                in self._plan:
            if two:
                raw = data[index] | data[index + 1] << 8
                if enc == 's16le' and raw & 0x8000:
                    raw -= 0x10000
            else:
                raw = (data[index] >> lo_bit) & mask
                if enc == 'twos_complement' and raw >> (width - 1):
                    raw -= 1 << width
            if enc == 'enum':
                if raw not in names:
                    raise RecordError(self.name, 'unknown enum value', code=Reject.BAD_VALUE,
                                      byte=f.byte, field=name, value=raw)
                out[name] = names[raw]
            elif lo <= raw <= hi or raw in special:
                out[name] = raw
            else:
                raise RecordError(self.name, f'value out of range {self._range_text(f)}',
                                  code=Reject.BAD_VALUE, byte=f.byte, field=name, value=raw)
        return out

    @functools.cached_property
    def _compiled(self) -> tuple[Callable, Callable]:
        return compile_fast_paths(self)

    @functools.cached_property
    def _port_paths(self) -> dict[str, tuple[Callable, Callable]]:
        return {}

    def port_paths(self, integrity: str) -> tuple[Callable, Callable] | None:
        """Return (seal, check) of whole records in `integrity`.

        In C where it was built (records/compiled_paths.py), else the generated Python
        (records/fast_paths.py): the same results.

        None for an unknown mode, which only the general path may name.
        """
        if integrity not in INTEGRITY_MODES:
            return None
        if (paths := self._port_paths.get(integrity)) is None:
            paths = self._port_paths[integrity] = compiled_port_paths(self, integrity) \
                or compile_port_paths(self, integrity)
        return paths


def _check_integrity(record: str, integrity: str) -> None:
    if integrity not in INTEGRITY_MODES:
        raise RecordError(record, f'unknown integrity mode (one of {INTEGRITY_MODES})',
                          code=Reject.UNKNOWN_INTEGRITY, value=integrity)


def e2e_counter(data: bytes | bytearray) -> int:
    """Return the sequence counter (byte 15) of a protected record."""
    return data[COUNTER_BYTE - 1]
