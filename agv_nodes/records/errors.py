"""What can go wrong with a record or a schema file, and why a record was refused.

`RecordError`'s `code` (a `Reject`) says why in one word, for ports to count rejections by reason;
its message names the record, byte, field and value for a person.
"""

import enum
from typing import Any


class Reject(enum.StrEnum):
    """Why a record was refused: the value is the counter key `/diagnostics` shows."""

    # the received bytes themselves are corrupt
    WRONG_LENGTH = 'wrong_length'  # not 16 bytes
    BAD_CRC = 'bad_crc'  # byte 16 does not match data_id and bytes 1-15
    SPARE_SET = 'spare_set'  # a bit no field claims, or byte 15-16 without E2E, is not 0
    BAD_VALUE = 'bad_value'  # out of range, an unknown enum code or name, not an integer
    # the caller asked for something the schemas do not have
    UNKNOWN_FIELD = 'unknown_field'
    UNKNOWN_RECORD = 'unknown_record'
    UNKNOWN_INTEGRITY = 'unknown_integrity'


class RecordError(ValueError):
    """A record that does not fit its schema (the only exception encode/decode raise)."""

    def __init__(self, record: str, reason: str, *, code: Reject, byte: int | None = None,
                 field: str | None = None, value: Any = None) -> None:
        self.record, self.reason, self.code = record, reason, code
        self.byte, self.field, self.value = byte, field, value  # where, when known
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
