"""The 16-byte records: schemas (msg_schemas/), the one codec, E2E protection and ports."""

from agv_nodes.records.codec import (
    Codec,
    RecordError,
    RecordSchema,
    SchemaError,
    codec,
    load_codec,
)
from agv_nodes.records.ports import RecordReader, RecordWriter

__all__ = ['Codec', 'RecordError', 'RecordReader', 'RecordSchema', 'RecordWriter', 'SchemaError',
           'codec', 'load_codec']
