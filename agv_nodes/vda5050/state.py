"""What a truck reports: the state message (6.10) and the visualization message (6.13).

The state carries the progress of the order (nodeStates, edgeStates, actionStates), the
truck's position, loads, battery, errors and safety state; visualization repeats position and
velocity at a higher rate.
"""

from enum import StrEnum

from pydantic import Field

from agv_nodes.vda5050.common import (
    Angle,
    Header,
    NodePosition,
    Omittable,
    Trajectory,
    Uint32,
    Vda5050Model,
    WholeNumber,
)


class MapStatus(StrEnum):
    """Whether a map on the truck is in use (6.7.2)."""

    ENABLED = 'ENABLED'
    DISABLED = 'DISABLED'


class Map(Vda5050Model):
    """A map stored on the truck (6.7.2, 6.10.6)."""

    map_id: str
    map_version: str
    map_description: Omittable[str] = None
    map_status: MapStatus


class NodeState(Vda5050Model):
    """A node of the order still to be traversed (6.10.6)."""

    node_id: str
    sequence_id: Uint32
    node_description: Omittable[str] = None
    released: bool
    node_position: Omittable[NodePosition] = None


class EdgeState(Vda5050Model):
    """An edge of the order still to be traversed (6.10.6)."""

    edge_id: str
    sequence_id: Uint32
    edge_description: Omittable[str] = None
    released: bool
    trajectory: Omittable[Trajectory] = None


class AgvPosition(Vda5050Model):
    """The truck's pose on a map (6.10.6)."""

    position_initialized: bool
    localization_score: Omittable[float] = Field(None, ge=0, le=1)
    deviation_range: Omittable[float] = None
    x: float
    y: float
    # 6.10.6 gives the range [-Pi ... Pi]; the state schema gives none: the text applies.
    theta: Angle
    map_id: str
    map_description: Omittable[str] = None


class Velocity(Vda5050Model):
    """The truck's velocity in its own coordinates (6.10.6)."""

    vx: Omittable[float] = None
    vy: Omittable[float] = None
    omega: Omittable[float] = None


class BoundingBoxReference(Vda5050Model):
    """Centre of a load's bounding box bottom, in truck coordinates (6.10.6)."""

    x: float
    y: float
    z: float
    theta: Omittable[float] = None


class LoadDimensions(Vda5050Model):
    """Size of a load's bounding box in metres (6.10.6)."""

    length: float
    width: float
    height: Omittable[float] = None


class Load(Vda5050Model):
    """A load the truck carries (6.10.6); every field is optional."""

    load_id: Omittable[str] = None
    load_type: Omittable[str] = None
    load_position: Omittable[str] = None
    bounding_box_reference: Omittable[BoundingBoxReference] = None
    load_dimensions: Omittable[LoadDimensions] = None
    weight: Omittable[float] = Field(None, ge=0)


class ActionStatus(StrEnum):
    """Where an action is in its life cycle (6.11)."""

    # The state schema's enum lacks 'PAUSED'; 6.10.6 and 6.11 have it: the text applies.
    WAITING = 'WAITING'
    INITIALIZING = 'INITIALIZING'
    RUNNING = 'RUNNING'
    PAUSED = 'PAUSED'
    FINISHED = 'FINISHED'
    FAILED = 'FAILED'


class ActionState(Vda5050Model):
    """The status of one action of the order or of an instant action (6.10.6)."""

    action_id: str
    action_type: Omittable[str] = None
    action_description: Omittable[str] = None
    action_status: ActionStatus
    result_description: Omittable[str] = None


class BatteryState(Vda5050Model):
    """Battery charge, health and charging (6.10.6)."""

    # A percentage (6.10.6 gives the unit %; neither the text nor the schema states the bounds).
    battery_charge: float = Field(ge=0, le=100)
    battery_voltage: Omittable[float] = None
    # 6.10.6 types batteryHealth int8 and reach uint32, the schema both "number": the text applies.
    battery_health: Omittable[WholeNumber] = Field(None, ge=0, le=100)
    charging: bool
    reach: Omittable[Uint32] = None


class ErrorLevel(StrEnum):
    """How grave an error is (6.10.5)."""

    WARNING = 'WARNING'  # resolves itself
    FATAL = 'FATAL'  # needs a person


class ErrorReference(Vda5050Model):
    """What an error refers to, e.g. a nodeId or the field of an order (6.10.6, 7.1)."""

    reference_key: str
    reference_value: str


class Error(Vda5050Model):
    """An active error of the truck (6.10.6)."""

    error_type: str
    error_references: Omittable[list[ErrorReference]] = None
    error_description: Omittable[str] = None
    error_hint: Omittable[str] = None
    error_level: ErrorLevel


class InfoLevel(StrEnum):
    """What an information is for (6.10.6)."""

    DEBUG = 'DEBUG'
    INFO = 'INFO'


class InfoReference(Vda5050Model):
    """What an information refers to (6.10.6)."""

    reference_key: str
    reference_value: str


class Info(Vda5050Model):
    """Information for visualization or debugging, never for a master control's logic (6.10.4)."""

    info_type: str
    info_references: Omittable[list[InfoReference]] = None
    info_description: Omittable[str] = None
    info_level: InfoLevel


class EStop(StrEnum):
    """Which kind of emergency stop is active, and how it is acknowledged (6.10.6)."""

    AUTOACK = 'AUTOACK'
    MANUAL = 'MANUAL'
    REMOTE = 'REMOTE'
    NONE = 'NONE'


class SafetyState(Vda5050Model):
    """Emergency stop and protective field (6.10.6)."""

    e_stop: EStop
    field_violation: bool


class OperatingMode(StrEnum):
    """Who controls the truck (6.10.6, table 1)."""

    AUTOMATIC = 'AUTOMATIC'
    SEMIAUTOMATIC = 'SEMIAUTOMATIC'
    MANUAL = 'MANUAL'
    SERVICE = 'SERVICE'
    TEACHIN = 'TEACHIN'


class State(Header):
    """The truck's whole state (6.10.6), sent on events and at least every 30 s (6.10)."""

    maps: Omittable[list[Map]] = None
    order_id: str  # '' when there has been no order
    order_update_id: Uint32
    zone_set_id: Omittable[str] = None
    last_node_id: str  # '' when there is none
    last_node_sequence_id: Uint32
    node_states: list[NodeState]
    edge_states: list[EdgeState]
    agv_position: Omittable[AgvPosition] = None
    velocity: Omittable[Velocity] = None
    # Left out when the truck cannot tell its load; [] means it carries none (6.10.6).
    loads: Omittable[list[Load]] = None
    driving: bool
    paused: Omittable[bool] = None
    new_base_request: Omittable[bool] = None
    distance_since_last_node: Omittable[float] = None
    action_states: list[ActionState]
    battery_state: BatteryState
    operating_mode: OperatingMode
    errors: list[Error]
    information: Omittable[list[Info]] = None
    safety_state: SafetyState


class Visualization(Header):
    """Position and velocity at a higher rate, for visualization only (6.13)."""

    # The visualization schema makes every field optional, the header too; 6.4 says every
    # message starts with the header, so it is required here as in the other messages.
    agv_position: Omittable[AgvPosition] = None
    velocity: Omittable[Velocity] = None
