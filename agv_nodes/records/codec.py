"""The one record codec: loads msg_schemas/*.yaml and packs/unpacks every 16-byte record.

Byte numbers follow the thesis (1-16). Inter-processor records keep bytes 15-16 for end-to-end
protection (`integrity='e2e'`: counter and CRC-8, see e2e.py) or require them to be 00H
(`integrity='none'`: a legacy peer sending plain thesis records). Hardware-side records use all
16 bytes and carry no protection. Every bit that no field claims is spare and must be 0.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
import functools
from pathlib import Path
from typing import Any

import yaml

from agv_nodes.records.e2e import record_crc

RECORD_LENGTH = 16
COUNTER_BYTE = 15
CRC_BYTE = 16
INTEGRITY_MODES = ('e2e', 'none')
KINDS = ('inter_processor', 'hardware', 'ground_truth')
ENCODINGS = ('flag', 'unsigned', 'twos_complement', 'enum', 'u16le', 's16le')
QOS_CLASSES = ('record', 'stream')


class RecordError(ValueError):
    """A record that does not fit its schema (the only exception encode/decode raise)."""

    def __init__(self, record: str, reason: str, *, byte: int | None = None,
                 field: str | None = None, value: Any = None) -> None:
        self.record = record
        self.reason = reason
        self.byte = byte
        self.field = field
        self.value = value
        where = [record]
        if byte is not None:
            where.append(f'byte {byte}')
        if field is not None:
            where.append(f'field {field!r}')
        text = ' '.join(where) + f': {reason}'
        if value is not None:
            text += f' (value {_show(value)})'
        super().__init__(text)


class SchemaError(ValueError):
    """A schema file that cannot be used; the message names the file, key and value."""


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return f'{value} = {value & 0xFFFF:02X}H' if value >= 0 else str(value)
    return repr(value)


def _parse_range(text: Any, what: str, file: Path, key: str) -> tuple[int, int]:
    """'3' / 3 -> (3, 3); '2-3' -> (2, 3); '6-1' -> (1, 6)."""
    try:
        if isinstance(text, int) and not isinstance(text, bool):
            return text, text
        lo, _, hi = str(text).partition('-')
        a, b = int(lo), int(hi or lo)
    except ValueError:
        raise SchemaError(f'{file}: key {key!r}: {what} {text!r} is not N or N-M') from None
    return min(a, b), max(a, b)


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
        """True when `raw` is a value this field may carry."""
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
        """The field called `name` (RecordError if there is none)."""
        for f in self.fields:
            if f.name == name:
                return f
        raise RecordError(self.name, 'no such field', field=name)

    def defaults(self) -> dict[str, Any]:
        """Every field at its documented default."""
        return {f.name: f.default for f in self.fields}

    def describe(self, fields: Mapping[str, Any]) -> dict[str, str]:
        """What each decoded value means, in words (for displays and `agv-records decode`)."""
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
        plan = []
        for f in self.fields:
            plan.append((f, f.name, f.byte - 1, f.n_bytes == 2, f.lo_bit, (1 << f.width) - 1,
                         f.width, f.encoding, f.lo, f.hi, frozenset(f.special), f.names,
                         f.values))
        return tuple(plan)

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
        if values is None:
            values = {}
        names = self._names
        for key in values:
            if key not in names:
                raise RecordError(self.name, 'no such field',
                                  field=sorted(set(values) - names)[0])
        if integrity not in INTEGRITY_MODES:
            _check_integrity(self.name, integrity)
        out = self._compiled[0](values)  # None: something the general path must judge
        if out is None:
            out = self._encode_fields(values)
        if self.protected and integrity == 'e2e':
            if not 0 <= counter <= 255:
                raise RecordError(self.name, 'e2e counter must be 0-255', byte=COUNTER_BYTE,
                                  field='e2e_counter', value=counter)
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
        if f.encoding == 'enum':
            if isinstance(value, str):
                if value not in f.values:
                    raise RecordError(self.name, f'unknown enum name (one of {list(f.values)})',
                                      byte=f.byte, field=f.name, value=value)
                return f.values[value]
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, int):
            if isinstance(value, str) and value in f.special.values():
                return next(k for k, v in f.special.items() if v == value)
            raise RecordError(self.name, 'value must be an integer', byte=f.byte,
                              field=f.name, value=value)
        if not f.valid(value):
            raise RecordError(self.name, f'value out of range {self._range_text(f)}',
                              byte=f.byte, field=f.name, value=value)
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
            raise RecordError(self.name, f'length {len(data)}, expected {RECORD_LENGTH} bytes')
        if integrity not in INTEGRITY_MODES:
            _check_integrity(self.name, integrity)
        check_spare = RECORD_LENGTH
        if self.protected:
            check_spare = 14
            if integrity == 'e2e':
                crc = record_crc(self.data_id, data[:15])
                if data[CRC_BYTE - 1] != crc:
                    raise RecordError(self.name, f'bad CRC, expected {crc:02X}H',
                                      byte=CRC_BYTE, field='e2e_crc', value=data[CRC_BYTE - 1])
            else:
                for byte in (COUNTER_BYTE, CRC_BYTE):
                    if data[byte - 1]:
                        raise RecordError(self.name, 'spare byte set (integrity none: 00H)',
                                          byte=byte, value=data[byte - 1])
        spare = self._spare_masks[0 if check_spare == 14 else 1]
        if int.from_bytes(data[:check_spare], 'big') & spare:
            for i in range(check_spare):
                stray = data[i] & ~self.used[i] & 0xFF
                if stray:
                    raise RecordError(self.name, f'spare bits set (mask {stray:02X}H), must be '
                                      '0', byte=i + 1, value=data[i])
        out = self._compiled[1](data)  # None: a value the general path must name
        return out if out is not None else self._decode_fields(data)

    def _decode_fields(self, data: bytes) -> dict[str, Any]:
        """The fields of checked bytes, one by one (the reference; raises for a bad value)."""
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
                    raise RecordError(self.name, 'unknown enum value', byte=f.byte, field=name,
                                      value=raw)
                out[name] = names[raw]
            elif lo <= raw <= hi or raw in special:
                out[name] = raw
            else:
                raise RecordError(self.name, f'value out of range {self._range_text(f)}',
                                  byte=f.byte, field=name, value=raw)
        return out

    @functools.cached_property
    def _compiled(self) -> tuple[Callable, Callable]:
        return compile_fast_paths(self)


def compile_fast_paths(schema: RecordSchema) -> tuple[Callable, Callable]:
    """(pack, unpack): straight-line Python for one schema's fields, generated once.

    `pack(values)` -> bytearray(16) with bytes 15-16 zero, and `unpack(data)` -> the field
    dict of 16 checked bytes, for records whose every value is a valid int (a bool for a
    flag, a name for an enum). They return None on anything else - a bool elsewhere, an enum
    code, a special value's name, a value out of range - and the general, field-by-field
    path (`_encode_fields`, `_decode_fields`) then decides and names the error, so the two can
    only differ in speed (test_records checks they agree). The loop over the plan cost ~1 us a
    field; the harness runs ~7 records a world sample, and every node packs and unpacks each
    record it sends and takes.
    """
    env: dict[str, Any] = {}
    pack = ['def pack(values):', '    get = values.get']
    unpack = ['def unpack(data):']
    byte_parts: list[list[str]] = [[] for _ in range(RECORD_LENGTH)]
    keys = []
    for k, f in enumerate(schema.fields):
        v, index = f'v{k}', f.byte - 1
        env[f'D{k}'], env[f'S{k}'] = f.default, frozenset(f.special)
        keys.append(f'{f.name!r}: {v}')
        # -- pack
        pack.append(f'    {v} = get({f.name!r}, D{k})')
        if f.encoding == 'flag':  # cores pass bools; the general path takes them as 0 / 1
            pack.append(f'    if type({v}) is bool: {v} = int({v})')
        if f.encoding == 'enum':
            env[f'C{k}'] = dict(f.values)
            pack += [f'    if type({v}) is not str: return None',
                     f'    {v} = C{k}.get({v})', f'    if {v} is None: return None']
        else:
            special = f' and {v} not in S{k}' if f.special else ''
            pack.append(f'    if type({v}) is not int or not {f.lo} <= {v} <= {f.hi}{special}: '
                        'return None')
        # -- unpack
        if f.n_bytes == 2:
            unpack.append(f'    {v} = data[{index}] | data[{index + 1}] << 8')
            if f.encoding == 's16le':
                unpack.append(f'    if {v} & 0x8000: {v} -= 0x10000')
            possible = (-0x8000, 0x7FFF) if f.encoding == 's16le' else (0, 0xFFFF)
            byte_parts[index].append(f'({v} & 0xFF)')
            byte_parts[index + 1].append(f'(({v} & 0xFFFF) >> 8)')
        else:
            width, mask = f.width, (1 << f.width) - 1
            read = f'data[{index}]' if f.lo_bit == 0 else f'(data[{index}] >> {f.lo_bit})'
            unpack.append(f'    {v} = {read}' if mask == 0xFF and not f.lo_bit else
                          f'    {v} = {read} & {mask}')
            if f.encoding == 'twos_complement':
                unpack.append(f'    if {v} >> {width - 1}: {v} -= {1 << width}')
                possible = (-(1 << (width - 1)), (1 << (width - 1)) - 1)
            else:
                possible = (0, mask)
            shift = f' << {f.lo_bit}' if f.lo_bit else ''
            byte_parts[index].append(f'(({v} & {mask}){shift})')
        if f.encoding == 'enum':
            env[f'N{k}'] = dict(f.names)
            unpack += [f'    {v} = N{k}.get({v})', f'    if {v} is None: return None']
        elif not (f.lo <= possible[0] and possible[1] <= f.hi):
            special = f' and {v} not in S{k}' if f.special else ''
            unpack.append(f'    if not {f.lo} <= {v} <= {f.hi}{special}: return None')
    pack.append('    return bytearray((' + ', '.join(' | '.join(p) or '0' for p in byte_parts)
                + '))')
    unpack.append('    return {' + ', '.join(keys) + '}')
    source = '\n'.join(pack) + '\n\n' + '\n'.join(unpack) + '\n'
    exec(compile(source, f'<codec {schema.name}>', 'exec'), env)  # noqa: S102
    return env['pack'], env['unpack']


def _check_integrity(record: str, integrity: str) -> None:
    if integrity not in INTEGRITY_MODES:
        raise RecordError(record, f'unknown integrity mode (one of {INTEGRITY_MODES})',
                          value=integrity)


def e2e_counter(data: bytes | bytearray) -> int:
    """The sequence counter (byte 15) of a protected record."""
    return data[COUNTER_BYTE - 1]


# -- schema loading --------------------------------------------------------------------------
_RECORD_KEYS = {'record', 'data_id', 'kind', 'topic', 'writer', 'readers', 'period_ms', 'qos',
                'thesis', 'summary', 'fields'}
_FIELD_KEYS = {'name', 'byte', 'bits', 'encoding', 'min', 'max', 'special', 'values', 'units',
               'scale', 'zero', 'one', 'default', 'thesis'}


def _need(mapping: Mapping, key: str, file: Path, where: str = '') -> Any:
    if key not in mapping:
        raise SchemaError(f'{file}: {where}missing key {key!r}')
    return mapping[key]


def _load_field(spec: Any, index: int, file: Path, last_byte: int) -> Field:
    where = f'fields[{index}]: '
    if not isinstance(spec, dict):
        raise SchemaError(f'{file}: {where}expected a mapping, got {spec!r}')
    extra = set(spec) - _FIELD_KEYS
    if extra:
        raise SchemaError(f'{file}: {where}unknown key {sorted(extra)[0]!r}')
    name = _need(spec, 'name', file, where)
    where = f'field {name!r}: '
    encoding = _need(spec, 'encoding', file, where)
    if encoding not in ENCODINGS:
        raise SchemaError(f"{file}: {where}key 'encoding': {encoding!r} not one of {ENCODINGS}")
    b0, b1 = _parse_range(_need(spec, 'byte', file, where), 'byte', file, f'{name}.byte')
    n_bytes = b1 - b0 + 1
    if not (1 <= b0 and b1 <= last_byte):
        raise SchemaError(f'{file}: {where}key \'byte\': {spec["byte"]!r} outside 1-{last_byte}')
    wide = encoding in ('u16le', 's16le')
    if wide != (n_bytes == 2) or n_bytes > 2:
        raise SchemaError(f'{file}: {where}key \'byte\': {spec["byte"]!r} does not fit '
                          f'encoding {encoding!r}')
    if wide:
        if 'bits' in spec:
            raise SchemaError(f"{file}: {where}key 'bits': not allowed on a 16-bit field")
        lo_bit, hi_bit = 0, 7
    else:
        lo_bit, hi_bit = _parse_range(spec.get('bits', '0-7'), 'bits', file, f'{name}.bits')
        if not 0 <= lo_bit <= hi_bit <= 7:
            raise SchemaError(f'{file}: {where}key \'bits\': {spec.get("bits")!r} outside 0-7')
    width = 16 if wide else hi_bit - lo_bit + 1
    signed = encoding in ('twos_complement', 's16le')
    full_lo, full_hi = (-(1 << (width - 1)), (1 << (width - 1)) - 1) if signed \
        else (0, (1 << width) - 1)
    values: dict[str, int] = {}
    if encoding == 'flag':
        if width != 1:
            raise SchemaError(f"{file}: {where}key 'bits': a flag is one bit")
        for key in ('zero', 'one'):
            _need(spec, key, file, where)
    if encoding == 'enum':
        values = dict(_need(spec, 'values', file, where))
        for vname, code in values.items():
            if not isinstance(vname, str):  # YAML 1.1 reads off/on/yes/no as booleans
                raise SchemaError(f"{file}: {where}key 'values': name {vname!r} is not a "
                                  'string (quote it)')
            if not isinstance(code, int) or not full_lo <= code <= full_hi:
                raise SchemaError(f"{file}: {where}key 'values.{vname}': {code!r} does not fit "
                                  f'{width} bits')
    lo = spec.get('min', full_lo)
    hi = spec.get('max', full_hi)
    if not (isinstance(lo, int) and isinstance(hi, int) and full_lo <= lo <= hi <= full_hi):
        raise SchemaError(f"{file}: {where}keys 'min'/'max': {lo!r}..{hi!r} do not fit "
                          f'{width} bits ({full_lo}..{full_hi})')
    raw_special = spec.get('special') or {}
    if not isinstance(raw_special, dict) or not all(
            isinstance(k, int) and not isinstance(k, bool) for k in raw_special):
        raise SchemaError(f"{file}: {where}key 'special': {raw_special!r} must map integer "
                          'codes to meanings')
    special = {k: str(v) for k, v in raw_special.items()}
    for code in special:
        if not full_lo <= code <= full_hi:
            raise SchemaError(f"{file}: {where}key 'special': {code!r} does not fit {width} bits")
    default = _need(spec, 'default', file, where)
    fld = Field(name=name, byte=b0, n_bytes=n_bytes, lo_bit=lo_bit, hi_bit=hi_bit,
                encoding=encoding, lo=lo, hi=hi, special=special, values=values, default=default,
                units=str(spec.get('units', '')), zero=str(spec.get('zero', '')),
                one=str(spec.get('one', '')), thesis=str(spec.get('thesis', '')),
                names={v: k for k, v in values.items()})
    ok = (default in values) if encoding == 'enum' else (
        isinstance(default, int) and fld.valid(default))
    if not ok:
        raise SchemaError(f"{file}: {where}key 'default': {default!r} is not a valid value")
    return fld


def load_schema(path: Path) -> RecordSchema:
    """Load and check one schema file (SchemaError names the file, key and value)."""
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        reason = ' '.join(str(exc).split())  # one line, whatever the YAML parser printed
        raise SchemaError(f'{path}: cannot read: {reason}') from None
    if not isinstance(doc, dict):
        raise SchemaError(f'{path}: expected a mapping at the top level')
    extra = set(doc) - _RECORD_KEYS
    if extra:
        raise SchemaError(f'{path}: unknown key {sorted(extra)[0]!r}')
    name = _need(doc, 'record', path)
    if name != path.stem:
        raise SchemaError(f"{path}: key 'record': {name!r} must equal the file name")
    kind = _need(doc, 'kind', path)
    if kind not in KINDS:
        raise SchemaError(f"{path}: key 'kind': {kind!r} not one of {KINDS}")
    data_id = _need(doc, 'data_id', path)
    if not isinstance(data_id, int) or not 0 <= data_id <= 255:
        raise SchemaError(f"{path}: key 'data_id': {data_id!r} is not a byte")
    qos = doc.get('qos', 'record')
    if qos not in QOS_CLASSES:
        raise SchemaError(f"{path}: key 'qos': {qos!r} not one of {QOS_CLASSES}")
    readers = _need(doc, 'readers', path)
    if not isinstance(readers, list) or not readers:
        raise SchemaError(f"{path}: key 'readers': {readers!r} must be a non-empty list")
    period = _need(doc, 'period_ms', path)
    if not isinstance(period, (int, float)) or period <= 0:
        raise SchemaError(f"{path}: key 'period_ms': {period!r} must be a positive number")
    topic = str(_need(doc, 'topic', path))
    if topic.startswith('/'):
        raise SchemaError(f"{path}: key 'topic': {topic!r} must be relative (no leading /)")
    last_byte = 14 if kind == 'inter_processor' else 16
    specs = _need(doc, 'fields', path)
    if not isinstance(specs, list) or not specs:
        raise SchemaError(f"{path}: key 'fields': must be a non-empty list")
    fields = tuple(_load_field(s, i, path, last_byte) for i, s in enumerate(specs))
    used = [0] * RECORD_LENGTH
    seen: set[str] = set()
    for f in fields:
        if f.name in seen:
            raise SchemaError(f"{path}: field {f.name!r}: key 'name': duplicate")
        seen.add(f.name)
        masks = [0xFF, 0xFF] if f.n_bytes == 2 else [f.mask]
        for offset, mask in enumerate(masks):
            i = f.byte - 1 + offset
            if used[i] & mask:
                raise SchemaError(f"{path}: field {f.name!r}: key 'byte': overlaps another "
                                  f'field in byte {i + 1}')
            used[i] |= mask
    return RecordSchema(name=name, data_id=data_id, kind=kind, topic=topic,
                        writer=str(_need(doc, 'writer', path)),
                        readers=tuple(str(r) for r in readers), period_ms=float(period), qos=qos,
                        thesis=str(doc.get('thesis', '')),
                        summary=' '.join(str(doc.get('summary', '')).split()),
                        fields=fields, path=path, used=tuple(used))


class Codec:
    """Every record schema of a schema directory, by name."""

    def __init__(self, schemas: Iterable[RecordSchema]) -> None:
        self._schemas: dict[str, RecordSchema] = {}
        ids: dict[int, str] = {}
        topics: dict[str, str] = {}
        for s in sorted(schemas, key=lambda s: s.name):
            if s.data_id in ids:
                raise SchemaError(f"{s.path}: key 'data_id': {s.data_id:#04x} already used by "
                                  f'{ids[s.data_id]}')
            if s.topic in topics:
                raise SchemaError(f"{s.path}: key 'topic': {s.topic!r} already used by "
                                  f'{topics[s.topic]}')
            ids[s.data_id] = s.name
            topics[s.topic] = s.name
            self._schemas[s.name] = s

    def __getitem__(self, name: str) -> RecordSchema:
        try:
            return self._schemas[name]
        except KeyError:
            raise RecordError(name, 'no such record (see agv-records list)') from None

    def __contains__(self, name: object) -> bool:
        return name in self._schemas

    def __iter__(self):
        return iter(self._schemas.values())

    def names(self) -> list[str]:
        """Record names, sorted."""
        return list(self._schemas)

    def encode(self, record: str, values: Mapping[str, Any] | None = None, *,
               integrity: str = 'e2e', counter: int = 0) -> bytes:
        """Pack a record by name."""
        return self[record].encode(values, integrity=integrity, counter=counter)

    def decode(self, record: str, data: bytes | bytearray | Iterable[int], *,
               integrity: str = 'e2e') -> dict[str, Any]:
        """Unpack a record by name."""
        return self[record].decode(data, integrity=integrity)

    def for_node(self, node: str) -> tuple[list[RecordSchema], list[RecordSchema]]:
        """The port declarations of `node`: (records it reads, records it writes)."""
        reads = [s for s in self if node in s.readers]
        writes = [s for s in self if s.writer == node]
        return reads, writes


def load_codec(directory: Path | str) -> Codec:
    """Load every `*.yaml` schema of `directory`."""
    directory = Path(directory)
    files = sorted(directory.glob('*.yaml'))
    if not files:
        raise SchemaError(f'{directory}: no record schemas (*.yaml) found')
    return Codec(load_schema(p) for p in files)


@functools.cache
def codec() -> Codec:
    """The installed package's codec (schemas loaded once per process)."""
    from agv_nodes.package_share import schema_dir

    return load_codec(schema_dir())
