"""The generated fast path of a record schema: straight-line pack and unpack of its fields."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from agv_nodes.records.schema import RECORD_LENGTH

if TYPE_CHECKING:
    from agv_nodes.records.schema import RecordSchema


def compile_fast_paths(schema: RecordSchema) -> tuple[Callable, Callable]:
    """(pack, unpack): straight-line Python for one schema's fields, generated once.

    `pack(values)` -> bytearray(16), bytes 15-16 zero; `unpack(data)` -> the field dict of 16
    checked bytes; for records whose every value is a valid int (a bool for a flag, a name for an
    enum). Anything else - a bool elsewhere, an enum code, a special value's name, a value out of
    range - returns None, and the general path (`_encode_fields`, `_decode_fields`) decides and
    names the error, so the two differ only in speed (test_records checks they agree). The loop
    over the plan cost ~1 us a field, on ~7 records a world sample in the harness and every record
    a node sends and takes.
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
