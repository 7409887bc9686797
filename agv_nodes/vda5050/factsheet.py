"""The factsheet (6.15): what a truck type is and what of the protocol it supports.

A master control reads it to plan with the truck and to know which optional fields and actions it
may send (6.1.1). The truck sends it retained, and again on a factsheetRequest action (6.15).
"""

from enum import StrEnum
from typing import Any

from pydantic import Field

from agv_nodes.vda5050.common import BlockingType, Header, Omittable, Uint32, Vda5050Model
from agv_nodes.vda5050.state import BoundingBoxReference, LoadDimensions


class AgvKinematic(StrEnum):
    """Simplified kinematics of the truck type."""

    DIFF = 'DIFF'  # differential drive
    OMNI = 'OMNI'  # omnidirectional
    THREEWHEEL = 'THREEWHEEL'  # three-wheel driven or similar


class AgvClass(StrEnum):
    """Simplified class of the truck type."""

    FORKLIFT = 'FORKLIFT'
    CONVEYOR = 'CONVEYOR'
    TUGGER = 'TUGGER'
    CARRIER = 'CARRIER'


# 6.15.1 lists the localization and navigation types as "example values"; the factsheet schema
# makes them enums. The enums are kept: the text names no other value.
class LocalizationType(StrEnum):
    """How the truck localizes itself."""

    NATURAL = 'NATURAL'  # natural landmarks
    REFLECTOR = 'REFLECTOR'  # laser reflectors
    RFID = 'RFID'
    DMC = 'DMC'  # data matrix codes
    SPOT = 'SPOT'  # magnetic spots
    GRID = 'GRID'  # magnetic grid


class NavigationType(StrEnum):
    """How the truck plans its path."""

    PHYSICAL_LINE_GUIDED = 'PHYSICAL_LINE_GUIDED'  # follows an installed path, e.g. a tape
    VIRTUAL_LINE_GUIDED = 'VIRTUAL_LINE_GUIDED'  # follows fixed virtual paths
    AUTONOMOUS = 'AUTONOMOUS'  # plans its own path


class TypeSpecification(Vda5050Model):
    """Class and capabilities of the truck type."""

    series_name: str
    series_description: Omittable[str] = None
    agv_kinematic: AgvKinematic
    agv_class: AgvClass
    max_load_mass: float = Field(ge=0)  # kg
    localization_types: list[LocalizationType]
    navigation_types: list[NavigationType]  # by priority


class PhysicalParameters(Vda5050Model):
    """Speeds, accelerations and size of the truck (SI units)."""

    speed_min: float
    speed_max: float
    # angularSpeedMin/Max are in 6.15.1 but not in the factsheet schema: the text applies.
    angular_speed_min: Omittable[float] = None
    angular_speed_max: Omittable[float] = None
    acceleration_max: float
    deceleration_max: float
    # 6.15.1 marks heightMin as required, the schema as optional: the text applies.
    height_min: float
    height_max: float
    width: float
    length: float


class MaxStringLens(Vda5050Model):
    """Longest strings the truck handles; absent or 0 means no limit."""

    msg_len: Omittable[Uint32] = None
    topic_serial_len: Omittable[Uint32] = None
    topic_elem_len: Omittable[Uint32] = None
    id_len: Omittable[Uint32] = None
    id_numerical_only: Omittable[bool] = None
    enum_len: Omittable[Uint32] = None
    load_id_len: Omittable[Uint32] = None


class MaxArrayLens(Vda5050Model):
    """Longest arrays the truck handles; absent or 0 means no limit."""

    # The wire names are dotted paths, which no alias generator produces.
    order_nodes: Omittable[Uint32] = Field(None, alias='order.nodes')
    order_edges: Omittable[Uint32] = Field(None, alias='order.edges')
    node_actions: Omittable[Uint32] = Field(None, alias='node.actions')
    edge_actions: Omittable[Uint32] = Field(None, alias='edge.actions')
    actions_actions_parameters: Omittable[Uint32] = Field(None,
                                                          alias='actions.actionsParameters')
    instant_actions: Omittable[Uint32] = None
    trajectory_knot_vector: Omittable[Uint32] = Field(None, alias='trajectory.knotVector')
    trajectory_control_points: Omittable[Uint32] = Field(None, alias='trajectory.controlPoints')
    state_node_states: Omittable[Uint32] = Field(None, alias='state.nodeStates')
    state_edge_states: Omittable[Uint32] = Field(None, alias='state.edgeStates')
    state_loads: Omittable[Uint32] = Field(None, alias='state.loads')
    state_action_states: Omittable[Uint32] = Field(None, alias='state.actionStates')
    state_errors: Omittable[Uint32] = Field(None, alias='state.errors')
    state_information: Omittable[Uint32] = Field(None, alias='state.information')
    error_error_references: Omittable[Uint32] = Field(None, alias='error.errorReferences')
    information_info_references: Omittable[Uint32] = Field(None,
                                                           alias='information.infoReferences')


class Timing(Vda5050Model):
    """Message intervals in seconds."""

    min_order_interval: float
    min_state_interval: float
    default_state_interval: Omittable[float] = None
    visualization_interval: Omittable[float] = None


class ProtocolLimits(Vda5050Model):
    """Limits of string lengths, array lengths and timing."""

    max_string_lens: MaxStringLens
    max_array_lens: MaxArrayLens
    timing: Timing


class Support(StrEnum):
    """How the truck stands to an optional parameter."""

    SUPPORTED = 'SUPPORTED'
    REQUIRED = 'REQUIRED'


class OptionalParameter(Vda5050Model):
    """An optional field of the protocol the truck supports or needs."""

    parameter: str  # full name, e.g. 'order.nodes.nodePosition.allowedDeviationTheta'
    support: Support
    description: Omittable[str] = None


class ActionScope(StrEnum):
    """Where an action type may be used."""

    INSTANT = 'INSTANT'
    NODE = 'NODE'
    EDGE = 'EDGE'


class ValueDataType(StrEnum):
    """Data type of an action parameter's value."""

    BOOL = 'BOOL'
    NUMBER = 'NUMBER'
    INTEGER = 'INTEGER'
    FLOAT = 'FLOAT'
    STRING = 'STRING'
    OBJECT = 'OBJECT'
    ARRAY = 'ARRAY'


class AgvActionParameter(Vda5050Model):
    """A parameter an action type takes (not the actionParameter of an order, 6.15.1)."""

    key: str
    value_data_type: ValueDataType
    description: Omittable[str] = None
    is_optional: Omittable[bool] = None


class AgvAction(Vda5050Model):
    """An action type the truck supports, standard or its own."""

    action_type: str
    action_description: Omittable[str] = None
    action_scopes: list[ActionScope]
    action_parameters: Omittable[list[AgvActionParameter]] = None
    result_description: Omittable[str] = None
    # 6.15.1: an array of blocking types. The factsheet schema puts the enum on the array itself,
    # which no array can satisfy; the text applies.
    blocking_types: Omittable[list[BlockingType]] = None


class ProtocolFeatures(Vda5050Model):
    """Optional fields and actions the truck supports."""

    optional_parameters: list[OptionalParameter]
    agv_actions: list[AgvAction]


class WheelType(StrEnum):
    """Kind of wheel."""

    DRIVE = 'DRIVE'
    CASTER = 'CASTER'
    FIXED = 'FIXED'
    MECANUM = 'MECANUM'


class WheelPosition(Vda5050Model):
    """Where a wheel sits, in truck coordinates (m, rad)."""

    x: float
    y: float
    theta: Omittable[float] = None  # needed for fixed wheels


class WheelDefinition(Vda5050Model):
    """One wheel of the truck."""

    wheel_type: WheelType = Field(alias='type')
    is_active_driven: bool
    is_active_steered: bool
    position: WheelPosition
    diameter: float
    width: float
    center_displacement: Omittable[float] = None  # 0 when absent; for caster wheels
    constraints: Omittable[str] = None


class PolygonPoint(Vda5050Model):
    """A corner of a 2D envelope, in truck coordinates (m)."""

    x: float
    y: float


class Envelope2d(Vda5050Model):
    """A closed, non-self-intersecting 2D outline of the truck, e.g. loaded or a safety field."""

    set_name: str = Field(alias='set')
    polygon_points: list[PolygonPoint]
    description: Omittable[str] = None


class Envelope3d(Vda5050Model):
    """A 3D outline of the truck, given inline or by a download URL."""

    set_name: str = Field(alias='set')
    format: str  # e.g. 'DXF'
    data: Omittable[dict[str, Any]] = None
    url: Omittable[str] = None
    # 6.15.1 types the description a string, the factsheet schema an integer: the text applies.
    description: Omittable[str] = None


class AgvGeometry(Vda5050Model):
    """Wheels and outlines of the truck."""

    wheel_definitions: Omittable[list[WheelDefinition]] = None
    # to_camel would capitalise the letter after the digit.
    envelopes2d: Omittable[list[Envelope2d]] = Field(None, alias='envelopes2d')
    envelopes3d: Omittable[list[Envelope3d]] = Field(None, alias='envelopes3d')


class LoadSet(Vda5050Model):
    """A kind of load the truck can handle, and how."""

    set_name: str
    load_type: str
    load_positions: Omittable[list[str]] = None  # absent or empty: every load position
    bounding_box_reference: Omittable[BoundingBoxReference] = None
    load_dimensions: Omittable[LoadDimensions] = None
    max_weight: Omittable[float] = None
    min_loadhandling_height: Omittable[float] = None
    max_loadhandling_height: Omittable[float] = None
    min_loadhandling_depth: Omittable[float] = None
    max_loadhandling_depth: Omittable[float] = None
    min_loadhandling_tilt: Omittable[float] = None
    max_loadhandling_tilt: Omittable[float] = None
    agv_speed_limit: Omittable[float] = None
    agv_acceleration_limit: Omittable[float] = None
    agv_deceleration_limit: Omittable[float] = None
    pick_time: Omittable[float] = None
    drop_time: Omittable[float] = None
    description: Omittable[str] = None


class LoadSpecification(Vda5050Model):
    """Load handling devices and load sets of the truck."""

    # The valid state.loads[].loadPosition values and 'lhd' parameters; absent or empty: no
    # load handling device.
    load_positions: Omittable[list[str]] = None
    load_sets: Omittable[list[LoadSet]] = None


class VersionInfo(Vda5050Model):
    """A software or hardware version on the truck, e.g. key 'softwareVersion'."""

    key: str
    value: str


class Network(Vda5050Model):
    """The truck's network settings, fixed while it operates."""

    dns_servers: Omittable[list[str]] = None
    ntp_servers: Omittable[list[str]] = None
    local_ip_address: Omittable[str] = None
    netmask: Omittable[str] = None
    default_gateway: Omittable[str] = None


class VehicleConfig(Vda5050Model):
    """Versions and network information of this truck."""

    versions: Omittable[list[VersionInfo]] = None
    network: Omittable[Network] = None


class Factsheet(Header):
    """The factsheet message (6.15.1)."""

    # 6.15.1 marks headerId and timestamp as required like every header (6.4); the factsheet
    # schema leaves them optional. The text applies.
    type_specification: TypeSpecification
    physical_parameters: PhysicalParameters
    protocol_limits: ProtocolLimits
    protocol_features: ProtocolFeatures
    agv_geometry: AgvGeometry
    load_specification: LoadSpecification
    vehicle_config: Omittable[VehicleConfig] = None
