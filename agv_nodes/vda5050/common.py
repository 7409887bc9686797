"""What every VDA 5050 2.1 message shares: the model base, the header, and the common objects.

The rules of the wire format live here once: camelCase names (6.1), optional fields that are
left out rather than sent as null (6.1.1), no NaN or infinity (6.1.4), uint32 counters, angles
in [-Pi, Pi] (6.7) and the header's UTC timestamp (6.4). The objects an order and a state
both carry (node position, NURBS trajectory, action) are defined here for that reason.

Where the standard's text and its JSON schemas differ, the text applies (section 6 says so);
the models follow the text and say so where they do.
"""

from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from enum import StrEnum
import math
import re
from typing import Annotated, Any, TypeVar

from pydantic import (
    AfterValidator,
    AwareDatetime,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PlainSerializer,
    PlainValidator,
    ValidationInfo,
)
from pydantic.alias_generators import to_camel

UINT32_MAX = 2**32 - 1
# The schemas bound angles by Pi rounded up to 11 decimals (3.14159265359 > math.pi), so an
# angle of exactly math.pi, or the schema's own bound, is accepted.
PI_BOUND = 3.14159265359
# allowedDeviationTheta has its own rounding of Pi in the order schema.
DEVIATION_THETA_BOUND = 3.141592654

T = TypeVar('T')


def _whole_number(value: Any) -> Any:
    # JSON has one number type and JSON Schema counts 2.0 as an integer, so a sender whose
    # numbers are all floats (1.0 for 1) is not wrong; held and sent as an int.
    if isinstance(value, float) and value.is_integer():
        return int(value)
    return value


WholeNumber = Annotated[int, BeforeValidator(_whole_number)]
Uint32 = Annotated[WholeNumber, Field(ge=0, le=UINT32_MAX)]
Angle = Annotated[float, Field(ge=-PI_BOUND, le=PI_BOUND)]


def _no_null_on_the_wire(value: Any, info: ValidationInfo) -> Any:
    # 6.1.1: an optional field is either present with a value of its type or left out; the
    # schemas give no field a null type. Python code may pass None for "left out".
    if value is None and info.mode == 'json':
        raise ValueError('null is not a value of this field; leave the field out instead')
    return value


# An optional field (italic in the standard's tables): None in Python, absent on the wire.
Omittable = Annotated[T | None, BeforeValidator(_no_null_on_the_wire)]

# RFC 3339 (the schemas' "date-time" format), a profile of ISO 8601; the zone is mandatory.
_DATE_TIME = re.compile(r'\d{4}-\d{2}-\d{2}[Tt]\d{2}:\d{2}:\d{2}(\.\d+)?([Zz]|[+-]\d{2}:\d{2})')


def _date_time(value: Any) -> Any:
    if isinstance(value, datetime):
        if value.tzinfo is None:
            raise ValueError('a timestamp needs a time zone; the standard uses UTC')
        return value
    if isinstance(value, str) and _DATE_TIME.fullmatch(value):
        try:
            return datetime.fromisoformat(value.upper())
        except ValueError as error:  # e.g. hour 25
            raise ValueError(f'not a valid date-time: {error}') from None
    raise ValueError('must be an ISO 8601 UTC date-time text like 2017-04-15T11:40:03.12Z')


def _utc_milliseconds(value: datetime) -> datetime:
    # Held as we send it (UTC, whole milliseconds), so a message equals itself after a round trip.
    value = value.astimezone(UTC)
    return value.replace(microsecond=value.microsecond // 1000 * 1000)


def format_timestamp(value: datetime) -> str:
    """Return the header timestamp text: ISO 8601 UTC, milliseconds and 'Z' (6.4).

    6.4 writes the pattern as YYYY-MM-DDTHH:mm:ss.ffZ; three decimals are the same format with
    one more digit of precision.
    """
    value = value.astimezone(UTC)
    return value.strftime('%Y-%m-%dT%H:%M:%S.') + f'{value.microsecond // 1000:03d}Z'


def now() -> datetime:
    """Return the current time as a header timestamp holds it (UTC, whole milliseconds)."""
    return _utc_milliseconds(datetime.now(UTC))


Timestamp = Annotated[AwareDatetime, BeforeValidator(_date_time),
                      AfterValidator(_utc_milliseconds),
                      PlainSerializer(format_timestamp, return_type=str, when_used='json')]


def _check_finite(value: Any) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError('NaN and infinity are not JSON numbers (6.1.4)')
    if isinstance(value, Mapping):
        for item in value.values():
            _check_finite(item)
    elif isinstance(value, Sequence) and not isinstance(value, str):
        for item in value:
            _check_finite(item)


def _parameter_value(value: Any) -> Any:
    # 7.2: one of array, boolean, number, string or object, and never null.
    if value is None or not isinstance(value, bool | int | float | str | list | dict):
        raise ValueError('must be an array, boolean, number, string or object')
    _check_finite(value)
    return value


ParameterValue = Annotated[bool | int | float | str | list[Any] | dict[str, Any],
                           PlainValidator(_parameter_value)]


class Vda5050Model(BaseModel):
    """Base of every VDA 5050 object: snake_case in Python, camelCase on the wire (6.1)."""

    # None of the 2.1 JSON schemas sets additionalProperties to false, and section 4 leaves the
    # JSON open to extension by further parameters: an object may carry fields the standard does
    # not define. They are kept (model_extra) rather than dropped, so that a receiver sees what
    # it was sent and a message survives a round trip unchanged.
    model_config = ConfigDict(alias_generator=to_camel, populate_by_name=True, extra='allow',
                              allow_inf_nan=False)


class Header(Vda5050Model):
    """The protocol header every message starts with (6.4), as top-level fields, not an object."""

    header_id: Uint32
    timestamp: Timestamp
    version: str
    manufacturer: str
    serial_number: str


class BlockingType(StrEnum):
    """Whether an action lets the truck drive and other actions run alongside it (6.12)."""

    NONE = 'NONE'
    SOFT = 'SOFT'
    HARD = 'HARD'


class ActionParameter(Vda5050Model):
    """One key-value parameter of an action (7.2)."""

    key: str
    value: ParameterValue


class Action(Vda5050Model):
    """An action on a node, on an edge, or sent as an instant action (6.6.6, 6.8)."""

    action_type: str
    action_id: str
    action_description: Omittable[str] = None
    blocking_type: BlockingType
    action_parameters: Omittable[list[ActionParameter]] = None


class NodePosition(Vda5050Model):
    """Where a node is on a map, in the project's world coordinates (6.6.6)."""

    x: float
    y: float
    theta: Omittable[Angle] = None
    allowed_deviation_xy: Omittable[float] = Field(None, alias='allowedDeviationXY', ge=0)
    # 6.6.6 gives the range [0 ... Pi]; the order schema allows [-Pi ... Pi]: the text applies.
    allowed_deviation_theta: Omittable[float] = Field(None, ge=0, le=DEVIATION_THETA_BOUND)
    map_id: str
    map_description: Omittable[str] = None


class ControlPoint(Vda5050Model):
    """A control point of a NURBS trajectory (6.6.6)."""

    x: float
    y: float
    weight: Omittable[float] = Field(None, ge=0)


class Trajectory(Vda5050Model):
    """An edge's path as a NURBS curve (6.6.6)."""

    # 6.6.6 types the degree float64 with range [1 ... float64.max], the schemas an integer of at
    # least 1. A NURBS degree is a whole number: held as an int, and 2.0 is read as 2.
    degree: WholeNumber = Field(ge=1)
    knot_vector: list[Annotated[float, Field(ge=0, le=1)]]
    control_points: list[ControlPoint]
