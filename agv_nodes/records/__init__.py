"""The 16-byte records: schemas (msg_schemas/), the one codec, E2E protection and ports."""

from agv_nodes.records.codec import Codec, codec, load_codec
from agv_nodes.records.errors import RecordError, Reject, SchemaError
from agv_nodes.records.ports import RecordReader, RecordWriter
from agv_nodes.records.schema import RecordSchema

__all__ = ['Codec', 'Reject', 'RecordError', 'RecordReader', 'RecordSchema', 'RecordWriter',
           'SchemaError', 'codec', 'load_codec']
