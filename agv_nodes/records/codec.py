"""The codec: a directory's schemas by name, no two sharing a data_id or topic; the package's."""

from collections.abc import Iterable, Iterator, Mapping
import functools
from pathlib import Path
from typing import Any

from agv_nodes.package_share import schema_dir
from agv_nodes.records.errors import RecordError, Reject, SchemaError
from agv_nodes.records.loading import load_schema
from agv_nodes.records.schema import RecordSchema


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
            ids[s.data_id] = topics[s.topic] = s.name
            self._schemas[s.name] = s

    def __getitem__(self, name: str) -> RecordSchema:
        try:
            return self._schemas[name]
        except KeyError:
            raise RecordError(name, 'no such record (see agv-records list)',
                              code=Reject.UNKNOWN_RECORD) from None

    def __contains__(self, name: object) -> bool:
        return name in self._schemas

    def __iter__(self) -> Iterator[RecordSchema]:
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
        """Return the port declarations of `node`: (records it reads, records it writes)."""
        return [s for s in self if node in s.readers], [s for s in self if s.writer == node]


def load_codec(directory: Path | str) -> Codec:
    """Load every `*.yaml` schema of `directory`."""
    directory = Path(directory)
    if not (files := sorted(directory.glob('*.yaml'))):
        raise SchemaError(f'{directory}: no record schemas (*.yaml) found')
    return Codec(load_schema(p) for p in files)


@functools.cache
def codec() -> Codec:
    """Return the installed package's codec (schemas loaded once per process)."""
    return load_codec(schema_dir())
