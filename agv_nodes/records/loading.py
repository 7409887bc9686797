"""Loading one schema file (msg_schemas/*.yaml), every key checked: a typo fails at load."""

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from agv_nodes.package_share import read_mapping
from agv_nodes.records.errors import SchemaError
from agv_nodes.records.schema import (
    ENCODINGS,
    KINDS,
    QOS_CLASSES,
    RECORD_LENGTH,
    Field,
    RecordSchema,
)

_RECORD_KEYS = {'record', 'data_id', 'kind', 'topic', 'writer', 'readers', 'period_ms', 'qos',
                'thesis', 'summary', 'fields'}
_FIELD_KEYS = {'name', 'byte', 'bits', 'encoding', 'min', 'max', 'special', 'values', 'units',
               'scale', 'zero', 'one', 'default', 'thesis'}


def _need(mapping: Mapping, key: str, file: Path, where: str = '') -> Any:
    if key not in mapping:
        raise SchemaError(f'{file}: {where}missing key {key!r}')
    return mapping[key]


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


def _load_field(spec: Any, index: int, file: Path, last_byte: int) -> Field:
    where = f'fields[{index}]: '
    if not isinstance(spec, dict):
        raise SchemaError(f'{file}: {where}expected a mapping, got {spec!r}')
    if extra := set(spec) - _FIELD_KEYS:
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
    lo, hi = spec.get('min', full_lo), spec.get('max', full_hi)
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
    doc = read_mapping(path, SchemaError, _RECORD_KEYS)
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
