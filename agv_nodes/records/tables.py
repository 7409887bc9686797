"""Human-readable record tables (docs/records.md and `agv-records show`), from the schemas."""

from agv_nodes.records.codec import Codec
from agv_nodes.records.schema import Field, RecordSchema

HEADER = """# Record tables

Generated from `msg_schemas/*.yaml` by `agv-records doc --output docs/records.md`; do not edit
by hand (a test fails when this file is stale). Bytes are numbered 1-16 as the thesis counts;
bits 7 (MSB) to 0. Every bit no field claims is spare and must be 0.

**End-to-end protection** (inter-processor records only, parameter `record_integrity`):
with `e2e` (default) byte 15 is a sequence counter (+1 per publish, 255 wraps to 0) and byte 16
a CRC-8/SAE-J1850 (poly 1DH, init FFH, no reflection, xorout FFH; check("123456789") = 4BH)
over the record's `data_id` followed by bytes 1-15. A receiver rejects a bad CRC, a repeated
counter and one that went back, and counts skipped counters (up to 15) as lost. A jump of more
than 15 is rejected without moving the receiver's reference; it resynchronises on the 3rd
CRC-valid record of a run that jumps and continues itself (+1 each: the jumping record counts
as the first; records of other counters may come between), a restarted writer, or when told to.
With `none` (a legacy peer sending plain thesis records) bytes 15-16 are spare (00H).
Hardware-side and ground-truth records use all 16 bytes and carry no protection.

Every record travels as `std_msgs/msg/UInt8MultiArray` with exactly 16 data bytes and an empty
layout, on the relative topic named below.
"""


def _meaning(f: Field) -> str:
    if f.encoding == 'flag':
        return f'0 = {f.zero}; 1 = {f.one}'
    if f.encoding == 'enum':
        return ', '.join(f'{code} = {name}' for name, code in f.values.items())
    text = f.units
    if (f.lo, f.hi) != _full(f):
        text += f' (range {f.lo}..{f.hi})'
    if f.special:
        text += '; ' + ', '.join(f'{k:02X}H = {v}' for k, v in f.special.items())
    return text


def _full(f: Field) -> tuple[int, int]:
    w = f.width
    if f.encoding in ('twos_complement', 's16le'):
        return -(1 << (w - 1)), (1 << (w - 1)) - 1
    return 0, (1 << w) - 1


def _default(f: Field) -> str:
    if isinstance(f.default, int) and f.default >= 0:
        return f'{f.default} ({f.default:02X}H)' if f.default > 9 else str(f.default)
    return str(f.default)


def record_table(s: RecordSchema) -> str:
    """Markdown section for one record."""
    lines = [f'## `{s.name}`', '', f'- topic `{s.topic}`; writer `{s.writer}`; readers '
             f'{", ".join(s.readers)}', f'- data_id `{s.data_id:02X}H`; kind '
             f'{s.kind.replace("_", "-")}; QoS class {s.qos}; period {s.period_ms:g} ms',
             f'- thesis: {s.thesis}', '', s.summary, '',
             '| byte | bits | field | encoding | meaning / units | default | thesis |',
             '|---|---|---|---|---|---|---|']
    for f in s.fields:
        meaning = _meaning(f).replace('|', '/')
        lines.append(f'| {f.bytes_text()} | {f.bits_text()} | `{f.name}` | {f.encoding} | '
                     f'{meaning} | {_default(f)} | {f.thesis.replace("|", "/")} |')
    if s.protected:
        lines.append('| 15 | 7-0 | `e2e_counter` | unsigned | sequence counter (e2e) | 0 | '
                     'modern (AUTOSAR E2E) |')
        lines.append('| 16 | 7-0 | `e2e_crc` | unsigned | CRC-8/SAE-J1850 over data_id + '
                     'bytes 1-15 (e2e) | - | modern |')
    spare = [str(i + 1) for i, m in enumerate(s.used[:14 if s.protected else 16]) if m == 0]
    lines += ['', f'Spare bytes (00H): {", ".join(spare) if spare else "none"}.', '']
    return '\n'.join(lines)


def render_markdown(codec: Codec) -> str:
    """Return the whole docs/records.md."""
    parts = [HEADER, '| record | topic | writer | readers | data_id |', '|---|---|---|---|---|']
    for s in codec:
        parts.append(f'| [`{s.name}`](#{s.name}) | `{s.topic}` | {s.writer} | '
                     f'{", ".join(s.readers)} | {s.data_id:02X}H |')
    parts.append('')
    titles = {'inter_processor': '# Inter-processor records',
              'hardware': '# Hardware-side records',
              'ground_truth': '# Ground truth (simulation only)'}
    for kind, title in titles.items():
        parts += [title, '', *(record_table(s) for s in codec if s.kind == kind)]
    return '\n'.join(parts).rstrip() + '\n'
