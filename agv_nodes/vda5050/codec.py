"""JSON text to and from the models: `to_json` for what we send, `parse` for what we receive.

`parse` is strict as the JSON schemas are: no "5" for a number, no null for an optional field,
no snake_case names on the wire. What does not pass raises one MessageError listing every
offending field as a path like `nodes[2].nodePosition.x`, which the bridge reports as the error
references of a validationError (6.6.4.1, 7.1).
"""

from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

M = TypeVar('M', bound=BaseModel)

# The path of a problem with the message as a whole (not JSON, or not an object).
ROOT = '$'


class MessageError(ValueError):
    """A message that is not valid VDA 5050; `problems` lists its (field path, problem) pairs."""

    def __init__(self, message_type: str, problems: list[tuple[str, str]]) -> None:
        self.message_type = message_type
        self.problems = problems
        listed = '; '.join(f'{path}: {problem}' for path, problem in problems)
        super().__init__(f'invalid {message_type} message: {listed}')

    @property
    def paths(self) -> list[str]:
        """The offending fields' paths, in the order pydantic found them."""
        return [path for path, _ in self.problems]


def field_path(location: tuple[Any, ...]) -> str:
    """Return a pydantic error location as a path: `nodes[2].nodePosition.x`."""
    path = ''
    for part in location:
        if isinstance(part, int):
            path += f'[{part}]'
        else:
            path += f'.{part}' if path else str(part)
    return path or ROOT


def parse(model_cls: type[M], data: str | bytes | bytearray) -> M:
    """Return the message `data` (JSON text, e.g. an MQTT payload) as a `model_cls`.

    Raises MessageError naming every offending field when it is not valid.
    """
    try:
        return model_cls.model_validate_json(data, strict=True, by_alias=True, by_name=False)
    except ValidationError as error:
        problems = [(field_path(e['loc']), e['msg'].removeprefix('Value error, '))
                    for e in error.errors(include_url=False)]
        raise MessageError(model_cls.__name__, problems) from None


def to_json(message: BaseModel) -> str:
    """Return a message as the standard's JSON text: camelCase names, optional fields left out."""
    return message.model_dump_json(by_alias=True, exclude_none=True)
