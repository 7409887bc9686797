"""Straight-line Python generated once per schema: the codec's fast paths.

Every fast path returns None for anything it is not sure of, and its caller then takes the
general path of records/schema.py (`RecordSchema.encode`, `decode`, `_encode_fields`,
`_decode_fields`), which decides and names the error: the two differ only in speed
(test_records and test_delivery_paths check it). A loop over the schema's fields costs ~1 us a
field, on every record a node or the lock-step harness sends and takes.

- `compile_fast_paths`: (pack, unpack), the field bytes alone;
- `compile_port_paths`: (seal, check), whole records for one integrity mode, as the ports
  (records/ports.py) send and take them: E2E counter and CRC, spare bits, length.
"""

from collections.abc import Callable
from typing import Any

from agv_nodes.records.e2e import CRC_TABLE, INIT, XOROUT

RECORD_LENGTH = 16


def unpacked(f: Any) -> tuple[bool, tuple[int, int]]:
    """Return whether field `f` unpacks signed, and the range of raw values its bits can hold.

    Two bytes are signed as s16le, one byte's bits as twos_complement; a field whose whole
    range is valid needs no range check when unpacked.
    """
    width = f.width
    signed = f.encoding == ('s16le' if f.n_bytes == 2 else 'twos_complement')
    if signed:
        return True, (-(1 << (width - 1)), (1 << (width - 1)) - 1)
    return False, (0, (1 << width) - 1)


def _field_code(schema: Any, env: dict[str, Any],
                read: Callable[[int], str]) -> tuple[list[str], list[str], list[list[str]]]:
    """Return per field the lines that check `v<k>` for packing, and that unpack it.

    Also what each byte is made of (`byte_parts`); `read(i)` is the expression of byte index i.
    """
    pack: list[str] = []
    unpack: list[str] = []
    byte_parts: list[list[str]] = [[] for _ in range(RECORD_LENGTH)]
    for k, f in enumerate(schema.fields):
        v, index = f'v{k}', f.byte - 1
        env[f'D{k}'], env[f'S{k}'] = f.default, frozenset(f.special)
        # -- pack
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
        signed, possible = unpacked(f)
        if f.n_bytes == 2:
            unpack.append(f'    {v} = {read(index)} | {read(index + 1)} << 8')
            if signed:
                unpack.append(f'    if {v} & 0x8000: {v} -= 0x10000')
            byte_parts[index].append(f'({v} & 0xFF)')
            byte_parts[index + 1].append(f'(({v} & 0xFFFF) >> 8)')
        else:
            width, mask = f.width, (1 << f.width) - 1
            read_byte = read(index) if f.lo_bit == 0 else f'({read(index)} >> {f.lo_bit})'
            unpack.append(f'    {v} = {read_byte}' if mask == 0xFF and not f.lo_bit else
                          f'    {v} = {read_byte} & {mask}')
            if signed:
                unpack.append(f'    if {v} >> {width - 1}: {v} -= {1 << width}')
            shift = f' << {f.lo_bit}' if f.lo_bit else ''
            byte_parts[index].append(f'(({v} & {mask}){shift})')
        if f.encoding == 'enum':
            env[f'N{k}'] = dict(f.names)
            unpack += [f'    {v} = N{k}.get({v})', f'    if {v} is None: return None']
        elif not (f.lo <= possible[0] and possible[1] <= f.hi):
            special = f' and {v} not in S{k}' if f.special else ''
            unpack.append(f'    if not {f.lo} <= {v} <= {f.hi}{special}: return None')
    return pack, unpack, byte_parts


def _result(schema: Any) -> str:
    return '    return {' + ', '.join(f'{f.name!r}: v{k}'
                                      for k, f in enumerate(schema.fields)) + '}'


def _compile(source: str, env: dict[str, Any], name: str) -> dict[str, Any]:
    exec(compile(source, f'<codec {name}>', 'exec'), env)  # noqa: S102
    return env


def compile_fast_paths(schema: Any) -> tuple[Callable, Callable]:
    """(pack, unpack): straight-line Python for one schema's fields, generated once.

    `pack(values)` -> bytearray(16), bytes 15-16 zero; `unpack(data)` -> the field dict of 16
    checked bytes; for records whose every value is a valid int (a bool for a flag, a name for an
    enum). Anything else - a bool elsewhere, an enum code, a special value's name, a value out of
    range - returns None, and the general path (`_encode_fields`, `_decode_fields`) decides and
    names the error, so the two differ only in speed (test_records checks it).
    """
    env: dict[str, Any] = {}
    checks, unpack, byte_parts = _field_code(schema, env, lambda i: f'data[{i}]')
    pack = ['def pack(values):', '    get = values.get']
    pack += [f'    v{k} = get({f.name!r}, D{k})' for k, f in enumerate(schema.fields)]
    pack += checks
    pack.append('    return bytearray((' + ', '.join(' | '.join(p) or '0' for p in byte_parts)
                + '))')
    source = '\n'.join(pack) + '\n\ndef unpack(data):\n' + '\n'.join(unpack) + '\n' \
        + _result(schema) + '\n'
    env = _compile(source, env, schema.name)
    return env['pack'], env['unpack']


def compile_port_paths(schema: Any, integrity: str) -> tuple[Callable, Callable]:
    """(seal, check): whole records of one schema in one integrity mode ('e2e' or 'none').

    `seal(values, counter)` -> the 16 bytes `schema.encode(values, integrity=integrity,
    counter=counter)` gives, for `values` a dict that names every field once (no default to
    fill, so no unknown name either) and passes `compile_fast_paths`'s pack; else None.
    `check(data)` -> what `schema.decode(data, integrity=integrity)` gives for 16 bytes (type
    bytes) that pass every check and unpack fast; else None.
    """
    env: dict[str, Any] = {'T': CRC_TABLE}
    e2e = schema.protected and integrity == 'e2e'
    spare_bytes = 14 if schema.protected else RECORD_LENGTH
    checks, unpack, byte_parts = _field_code(schema, env, lambda i: f'd{i}')
    crc_start = CRC_TABLE[INIT ^ schema.data_id]
    n = len(schema.fields)

    # a plain dict only: a Mapping's __missing__ could answer for a name not in it
    seal = ['def seal(values, counter):',
            f'    if type(values) is not dict or len(values) != {n}: return None', '    try:']
    seal += [f'        v{k} = values[{f.name!r}]' for k, f in enumerate(schema.fields)]
    seal += ['    except KeyError:', '        return None']
    seal += checks
    out = [' | '.join(p) or '0' for p in byte_parts]
    if e2e:
        seal.append('    if not 0 <= counter <= 255: return None')
        seal += [f'    b{i} = {out[i]}' for i in range(14)]
        seal.append(f'    c = T[{crc_start} ^ b0]')
        seal += [f'    c = T[c ^ b{i}]' for i in range(1, 14)]
        seal.append(f'    c = T[c ^ counter] ^ {XOROUT}')
        out = [f'b{i}' for i in range(14)] + ['counter', 'c']
    elif schema.protected:
        out[14:] = ['0', '0']
    seal.append('    return bytes((' + ', '.join(out) + '))')

    check = ['def check(data):',
             f'    if type(data) is not bytes or len(data) != {RECORD_LENGTH}: return None',
             '    ' + ', '.join(f'd{i}' for i in range(RECORD_LENGTH)) + ' = data']
    if e2e:
        check.append(f'    c = T[{crc_start} ^ d0]')
        check += [f'    c = T[c ^ d{i}]' for i in range(1, 15)]
        check.append(f'    if d15 != c ^ {XOROUT}: return None')
    elif schema.protected:
        check.append('    if d14 or d15: return None')
    for i, used in enumerate(schema.used[:spare_bytes]):  # decode: bits no field claims
        if spare := ~used & 0xFF:
            check.append(f'    if d{i} & {spare}: return None')
    check += unpack
    check.append(_result(schema))
    env = _compile('\n'.join(seal) + '\n\n' + '\n'.join(check) + '\n', env,
                   f'{schema.name} {integrity}')
    return env['seal'], env['check']
