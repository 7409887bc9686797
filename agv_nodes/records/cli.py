"""agv-records: list, show, encode, decode and echo the 16-byte records; regenerate the tables.

`echo RECORD` prints a live record topic field by field with each record's E2E verdict
(agv_nodes/records/echo.py); RECORD may be a record's name or its topic.

Bad input exits with status 2 and a one-line reason on stderr, never a traceback.
"""

import argparse
from pathlib import Path
import sys
from typing import Any

import yaml

from agv_nodes.records.codec import Codec, load_codec
from agv_nodes.records.codec import codec as installed_codec
from agv_nodes.records.errors import RecordError, SchemaError
from agv_nodes.records.tables import record_table, render_markdown


class UsageError(Exception):
    """Bad command-line input (exit status 2)."""


def _parse_value(text: str) -> Any:
    """'12', '0x0B', '0BH', '-5' -> int; anything else stays a string (enum / special name)."""
    t = text.strip()
    try:
        if t.lower().endswith('h') and len(t) > 1:
            return int(t[:-1], 16)
        return int(t, 0)
    except ValueError:
        return t


def _parse_hex(text: str) -> bytes:
    t = ''.join(text.split()).replace(':', '')
    t = t[2:] if t.lower().startswith('0x') else t
    try:
        return bytes.fromhex(t)
    except ValueError:
        raise UsageError(f'not a hex string: {text!r}') from None


def _cmd_list(codec: Codec, _args: argparse.Namespace) -> None:
    for s in codec:
        print(f'{s.name:24s} {s.data_id:02X}H  {s.kind:16s} {s.topic:28s} '
              f'{s.writer} -> {", ".join(s.readers)}')


def _cmd_show(codec: Codec, args: argparse.Namespace) -> None:
    print(record_table(codec[args.record]))


def _cmd_encode(codec: Codec, args: argparse.Namespace) -> None:
    values: dict[str, Any] = {}
    for item in args.fields:
        name, sep, value = item.partition('=')
        if not sep or not name:
            raise UsageError(f'expected field=value, got {item!r}')
        values[name] = _parse_value(value)
    print(codec.encode(args.record, values, integrity=args.integrity,
                       counter=args.counter).hex().upper())


def _cmd_decode(codec: Codec, args: argparse.Namespace) -> None:
    schema = codec[args.record]
    fields = schema.decode(_parse_hex(args.hex), integrity=args.integrity)
    meaning = schema.describe(fields)
    for name, value in fields.items():
        line = yaml.safe_dump({name: value}, default_flow_style=True).strip()[1:-1]
        print(f'{line:32s} # {meaning[name]}')


def _cmd_echo(codec: Codec, args: argparse.Namespace) -> int:
    from agv_nodes.records.echo import find_schema, run

    try:
        find_schema(codec, args.record)
    except KeyError as exc:
        raise UsageError(exc.args[0]) from None
    return run(codec, args.record, args.integrity, args.count, args.timeout)


def _cmd_doc(codec: Codec, args: argparse.Namespace) -> None:
    text = render_markdown(codec)
    if args.check:
        current = Path(args.output).read_text() if Path(args.output).exists() else ''
        if current != text:
            raise UsageError(f'{args.output} is stale: run agv-records doc --output {args.output}')
        return
    if args.output == '-':
        sys.stdout.write(text)
    else:
        Path(args.output).write_text(text)


def build_parser() -> argparse.ArgumentParser:
    """Build the agv-records argument parser."""
    p = argparse.ArgumentParser(prog='agv-records', description=__doc__.splitlines()[0])
    p.add_argument('--schemas', help='schema directory (default: the installed msg_schemas/)')
    sub = p.add_subparsers(dest='command', required=True, metavar='COMMAND')
    sub.add_parser('list', help='every record: data_id, kind, topic, writer -> readers')
    show = sub.add_parser('show', help='the byte table of one record')
    show.add_argument('record')
    for name, helptext in (('encode', 'pack field=value pairs into 32 hex digits'),
                           ('decode', 'unpack 32 hex digits into fields (YAML)')):
        cmd = sub.add_parser(name, help=helptext)
        cmd.add_argument('record')
        if name == 'encode':
            cmd.add_argument('fields', nargs='*', metavar='field=value')
            cmd.add_argument('--counter', type=int, default=0, help='e2e counter (byte 15)')
        else:
            cmd.add_argument('hex')
        cmd.add_argument('--integrity', choices=('e2e', 'none'), default='e2e')
    echo = sub.add_parser('echo', help='print a live record topic field by field, with each '
                          "record's E2E verdict (as ros2 topic echo, decoded)")
    echo.add_argument('record', help='record name or topic (agv-records list)')
    echo.add_argument('--count', type=int, default=0, help='stop after N records (0: never)')
    echo.add_argument('--timeout', type=float, default=0.0,
                      help='stop after S s of wall time without a record, exit 1 if none came '
                      '(0: never)')
    echo.add_argument('--integrity', choices=('e2e', 'none'), default='e2e')
    doc = sub.add_parser('doc', help='regenerate the record tables (docs/records.md)')
    doc.add_argument('--output', default='-', help="file to write, '-' for stdout")
    doc.add_argument('--check', action='store_true', help='exit 2 if --output is stale')
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-records."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse already printed its one-line usage error
        return 2 if exc.code else 0
    handlers = {'list': _cmd_list, 'show': _cmd_show, 'encode': _cmd_encode, 'decode': _cmd_decode,
                'echo': _cmd_echo, 'doc': _cmd_doc}
    try:
        status = handlers[args.command](
            load_codec(args.schemas) if args.schemas else installed_codec(), args)
    except (RecordError, SchemaError, UsageError, OSError) as exc:
        print(f'agv-records: {exc}', file=sys.stderr)
        return 2
    return status or 0


if __name__ == '__main__':
    sys.exit(main())
