"""A record as a viewer plots it: its fields by name, with the reader's verdict, as JSON.

The 16 bytes stay the wire format (that is the design); a viewer (Foxglove, PlotJuggler) gets
beside each record topic a JSON channel of the same records decoded: every field of the record's
table in msg_schemas/ by name (enumerations as their names), the E2E counter, and the verdict a
node's reader reaches (`accepted`, or the rejection's reason). `json_schema` is the channel's
JSON schema, made from the same table, so a viewer knows each field's type before the first
message.
"""

from __future__ import annotations

from typing import Any

from agv_nodes.records.errors import RecordError
from agv_nodes.records.ports import RecordReader
from agv_nodes.records.schema import COUNTER_BYTE, RecordSchema

DECODED_PREFIX = 'decoded'  # the JSON channel of record topic `t` is `decoded/t`


def decoded_topic(schema: RecordSchema, namespace: str = '') -> str:
    """Return the JSON channel's topic beside the record topic (in the truck's namespace)."""
    ns = namespace.strip('/')
    return f'/{ns + "/" if ns else ""}{DECODED_PREFIX}/{schema.topic.lstrip("/")}'


def json_schema(schema: RecordSchema) -> dict[str, Any]:
    """Return the JSON schema of `schema`'s decoded records."""
    props: dict[str, Any] = {
        'verdict': {'type': 'string', 'description': 'accepted, or why the reader rejected it'},
        'raw': {'type': 'string', 'description': 'the 16 bytes, hex'},
    }
    if schema.protected:
        props['e2e_counter'] = {'type': 'integer', 'minimum': 0, 'maximum': 255}
    for f in schema.fields:
        if f.encoding == 'enum':
            props[f.name] = {'type': 'string', 'enum': sorted(f.values)}
        elif f.encoding == 'flag':
            props[f.name] = {'type': 'integer', 'enum': [0, 1]}
        else:
            props[f.name] = {'type': 'integer'}
        description = ' '.join(x for x in (f.units, f'(byte {f.bytes_text()})') if x)
        props[f.name]['description'] = description
    return {'$schema': 'https://json-schema.org/draft/2020-12/schema',
            'title': f'agv_nodes.{schema.name}', 'type': 'object', 'properties': props,
            'required': ['verdict', 'raw']}


def decoded(reader: RecordReader, raw: bytes, now_ns: int) -> dict[str, Any]:
    """Judge `raw` as `reader` (a node's reader of the topic) and return the JSON message.

    A rejected record carries its fields where the codec can still read the bytes (a repeated
    counter, say), and none where it cannot (a bad CRC): the verdict says which.
    """
    schema = reader.schema
    fields = reader.accept(raw, now_ns)
    message: dict[str, Any] = {'verdict': 'accepted' if fields is not None
                               else reader.last_reason, 'raw': raw.hex()}
    if fields is None:
        try:
            fields = schema.decode(raw, integrity=reader.integrity)
        except RecordError:
            fields = None
    if reader.integrity == 'e2e' and schema.protected and len(raw) >= COUNTER_BYTE:
        message['e2e_counter'] = raw[COUNTER_BYTE - 1]
    if fields is not None:
        message.update(fields)
    return message
