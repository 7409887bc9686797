"""The VDA 5050 2.1 message models (agv_nodes.vda5050) against the standard's own JSON schemas.

The schemas of tag 2.1.0 (test/data/vda5050_2.1.0) are the oracle: a full example of every
message, built with the models, must validate against its schema; the schemas' own example
values must parse; every field a schema defines must be in the models, with the same required
fields, enumerations and ranges. Where the schemas and the standard's text disagree, the models
follow the text (section 6 of the standard says it applies) and the places are listed here, so
that the schemas check everything else exactly. Bad input must raise MessageError naming the
field as `nodes[2].nodePosition.x`.
"""

import copy
from datetime import UTC, datetime, timedelta, timezone
from enum import Enum
import functools
import json
import math
from pathlib import Path
import re
import types
from typing import Annotated, Any, Union, get_args, get_origin

import annotated_types
from jsonschema import Draft202012Validator
from jsonschema.validators import validator_for
from pydantic import BaseModel
from pydantic.fields import FieldInfo
import pytest

from agv_nodes.vda5050 import VERSION
from agv_nodes.vda5050.codec import MessageError, field_path, parse, to_json
from agv_nodes.vda5050.common import (
    Action,
    ActionParameter,
    BlockingType,
    ControlPoint,
    NodePosition,
    Trajectory,
    format_timestamp,
    now,
)
from agv_nodes.vda5050.connection import Connection, ConnectionState
from agv_nodes.vda5050.factsheet import (
    ActionScope,
    AgvAction,
    AgvActionParameter,
    AgvClass,
    AgvGeometry,
    AgvKinematic,
    Envelope2d,
    Envelope3d,
    Factsheet,
    LoadSet,
    LoadSpecification,
    LocalizationType,
    MaxArrayLens,
    MaxStringLens,
    NavigationType,
    Network,
    OptionalParameter,
    PhysicalParameters,
    PolygonPoint,
    ProtocolFeatures,
    ProtocolLimits,
    Support,
    Timing,
    TypeSpecification,
    ValueDataType,
    VehicleConfig,
    VersionInfo,
    WheelDefinition,
    WheelPosition,
    WheelType,
)
from agv_nodes.vda5050.order import (
    Corridor,
    CorridorRefPoint,
    Edge,
    InstantActions,
    Node,
    Order,
    OrientationType,
)
from agv_nodes.vda5050.state import (
    ActionState,
    ActionStatus,
    AgvPosition,
    BatteryState,
    BoundingBoxReference,
    EdgeState,
    Error,
    ErrorLevel,
    ErrorReference,
    EStop,
    Info,
    InfoLevel,
    InfoReference,
    Load,
    LoadDimensions,
    Map,
    MapStatus,
    NodeState,
    OperatingMode,
    SafetyState,
    State,
    Velocity,
    Visualization,
)
from agv_nodes.vda5050.topics import AGV, MASTER_CONTROL, TOPICS, topic

pytestmark = pytest.mark.timeout(60)

SCHEMAS = Path(__file__).resolve().parent / 'data' / 'vda5050_2.1.0'
MESSAGES = {'order': Order, 'instantActions': InstantActions, 'state': State,
            'visualization': Visualization, 'connection': Connection, 'factsheet': Factsheet}
STAMP = datetime(2024, 8, 19, 16, 9, 39, 120000, tzinfo=UTC)
SENT_STAMP = re.compile(r'\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}\.\d{3}Z')  # 6.4, with milliseconds

# Where a 2.1.0 schema contradicts the standard's text, a message that uses what the text allows
# fails the schema there, and only there.
SCHEMA_DEFECTS_IN_EXAMPLES = {
    'state': {'actionStates[1].actionStatus'},  # 'PAUSED' (6.11) is missing from the enum
    'factsheet': {
        'protocolFeatures.agvActions[0].blockingTypes',  # the enum sits on the array itself
        'agvGeometry.envelopes3d[0].description',  # typed integer; 6.15.1: string
    },
}


# -- the official schemas --------------------------------------------------------------------

@functools.cache
def schema(name: str) -> dict:
    return json.loads((SCHEMAS / f'{name}.schema').read_text(encoding='utf-8'))


@functools.cache
def validator(name: str) -> Draft202012Validator:
    cls = validator_for(schema(name))  # the draft the schema's $schema names
    cls.check_schema(schema(name))
    return cls(schema(name))


def schema_error_paths(name: str, document: Any) -> set[str]:
    return {field_path(tuple(e.absolute_path)) for e in validator(name).iter_errors(document)}


# -- full examples, built with the models; together they set every field at least once -----

def header(header_id: int) -> dict:
    return {'header_id': header_id, 'timestamp': STAMP, 'version': VERSION,
            'manufacturer': 'Cableform', 'serial_number': 'truck-1'}


def order_example() -> Order:
    pick = Action(action_type='pick', action_id='pick-1', action_description='pallet at bay 3',
                  blocking_type=BlockingType.HARD, action_parameters=[
                      ActionParameter(key='stationType', value='floor'),
                      ActionParameter(key='height', value=0.25),
                      ActionParameter(key='loadCount', value=2),
                      ActionParameter(key='checkLoad', value=True),
                      ActionParameter(key='lhd', value=['LHD1']),
                      ActionParameter(key='geometry', value={'depth': 1.2, 'side': None})])
    nodes = [
        Node(node_id='n1', sequence_id=0, node_description='depot', released=True,
             node_position=NodePosition(x=0.0, y=0.0, theta=0.0, allowed_deviation_xy=0.05,
                                        allowed_deviation_theta=0.1, map_id='floor0',
                                        map_description='ground floor'), actions=[]),
        Node(node_id='n2', sequence_id=2, released=True, actions=[pick],
             node_position=NodePosition(x=5.0, y=0.0, theta=math.pi / 2, map_id='floor0')),
        Node(node_id='n3', sequence_id=4, released=False, actions=[],
             node_position=NodePosition(x=5.0, y=5.0, theta=-math.pi, map_id='floor0')),
    ]
    edges = [
        Edge(edge_id='e1', sequence_id=1, edge_description='main aisle', released=True,
             start_node_id='n1', end_node_id='n2', max_speed=1.0, max_height=2.0,
             min_height=0.1, orientation=0.0, orientation_type=OrientationType.TANGENTIAL,
             direction='straight', rotation_allowed=False, max_rotation_speed=0.5, length=5.0,
             trajectory=Trajectory(degree=1, knot_vector=[0, 0, 1, 1], control_points=[
                 ControlPoint(x=0, y=0, weight=1.0), ControlPoint(x=5, y=0)]),
             corridor=Corridor(left_width=0.5, right_width=0.5,
                               corridor_ref_point=CorridorRefPoint.CONTOUR),
             actions=[Action(action_type='activateWarningLights', action_id='lights-1',
                             blocking_type=BlockingType.NONE)]),
        Edge(edge_id='e2', sequence_id=3, released=False, start_node_id='n2', end_node_id='n3',
             orientation=math.pi / 2, orientation_type=OrientationType.GLOBAL, actions=[],
             trajectory=Trajectory(degree=2, knot_vector=[0, 0, 0, 1, 1, 1], control_points=[
                 ControlPoint(x=5, y=0), ControlPoint(x=5, y=2.5, weight=0.7),
                 ControlPoint(x=5, y=5)]),
             corridor=Corridor(left_width=0.3, right_width=0.0)),
    ]
    return Order(**header(7), order_id='order-1', order_update_id=0, zone_set_id='zones-a',
                 nodes=nodes, edges=edges)


def instant_actions_example() -> InstantActions:
    return InstantActions(**header(3), actions=[
        Action(action_type='startPause', action_id='pause-1', blocking_type=BlockingType.HARD),
        Action(action_type='initPosition', action_id='init-1', blocking_type=BlockingType.SOFT,
               action_description='after the lift', action_parameters=[
                   ActionParameter(key='x', value=1.5), ActionParameter(key='y', value=-2.0),
                   ActionParameter(key='theta', value=0.0),
                   ActionParameter(key='mapId', value='floor1'),
                   ActionParameter(key='lastNodeId', value='lift-1')])])


def state_example() -> State:
    trajectory = Trajectory(degree=1, knot_vector=[0, 0, 1, 1],
                            control_points=[ControlPoint(x=0, y=0), ControlPoint(x=5, y=0)])
    return State(
        **header(42), order_id='order-1', order_update_id=0, zone_set_id='zones-a',
        maps=[Map(map_id='floor0', map_version='3', map_description='ground floor',
                  map_status=MapStatus.ENABLED),
              Map(map_id='floor0', map_version='2', map_status=MapStatus.DISABLED)],
        last_node_id='n1', last_node_sequence_id=0,
        node_states=[NodeState(node_id='n2', sequence_id=2, node_description='bay 3',
                               released=True, node_position=NodePosition(
                                   x=5.0, y=0.0, theta=1.57, map_id='floor0'))],
        edge_states=[EdgeState(edge_id='e1', sequence_id=1, edge_description='main aisle',
                               released=True, trajectory=trajectory)],
        agv_position=AgvPosition(position_initialized=True, localization_score=0.93,
                                 deviation_range=0.02, x=1.2, y=0.01, theta=-0.01,
                                 map_id='floor0', map_description='ground floor'),
        velocity=Velocity(vx=0.8, vy=0.0, omega=0.01),
        loads=[Load(load_id='pallet-17', load_type='EPAL', load_position='front',
                    bounding_box_reference=BoundingBoxReference(x=0.5, y=0.0, z=0.1, theta=0.0),
                    load_dimensions=LoadDimensions(length=1.2, width=0.8, height=1.0),
                    weight=350.0)],
        driving=True, paused=False, new_base_request=False, distance_since_last_node=1.2,
        action_states=[
            ActionState(action_id='pick-1', action_type='pick', action_description='bay 3',
                        action_status=ActionStatus.FINISHED, result_description='pallet-17'),
            ActionState(action_id='lights-1', action_status=ActionStatus.PAUSED)],
        battery_state=BatteryState(battery_charge=81.5, battery_voltage=24.3, battery_health=97,
                                   charging=False, reach=12000),
        operating_mode=OperatingMode.AUTOMATIC,
        errors=[Error(error_type='orderError', error_level=ErrorLevel.WARNING,
                      error_references=[ErrorReference(reference_key='headerId',
                                                       reference_value='7')],
                      error_description='trajectory not supported',
                      error_hint='send orders without trajectories')],
        information=[Info(info_type='odometry', info_level=InfoLevel.DEBUG,
                          info_references=[InfoReference(reference_key='edgeId',
                                                         reference_value='e1')],
                          info_description='wheel slip corrected')],
        safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False))


def visualization_example() -> Visualization:
    return Visualization(**header(900), velocity=Velocity(vx=0.8, omega=0.0),
                         agv_position=AgvPosition(position_initialized=True, x=1.3, y=0.01,
                                                  theta=math.pi, map_id='floor0'))


def connection_example() -> Connection:
    return Connection(**header(1), connection_state=ConnectionState.CONNECTIONBROKEN)


def factsheet_example() -> Factsheet:
    pallet = LoadSet(
        set_name='DEFAULT', load_type='EPAL', load_positions=['front'], max_weight=1000.0,
        bounding_box_reference=BoundingBoxReference(x=0.6, y=0.0, z=0.0),
        load_dimensions=LoadDimensions(length=1.2, width=0.8), min_loadhandling_height=0.0,
        max_loadhandling_height=1.5, min_loadhandling_depth=0.0, max_loadhandling_depth=1.2,
        min_loadhandling_tilt=-0.05, max_loadhandling_tilt=0.05, agv_speed_limit=1.0,
        agv_acceleration_limit=0.5, agv_deceleration_limit=0.8, pick_time=20.0, drop_time=15.0,
        description='Euro pallet')
    return Factsheet(
        **header(1),
        type_specification=TypeSpecification(
            series_name='Cableform tow truck', series_description='wire-guided tugger',
            agv_kinematic=AgvKinematic.THREEWHEEL, agv_class=AgvClass.TUGGER, max_load_mass=2000,
            localization_types=[LocalizationType.RFID, LocalizationType.SPOT],
            navigation_types=[NavigationType.PHYSICAL_LINE_GUIDED]),
        physical_parameters=PhysicalParameters(
            speed_min=0.05, speed_max=1.4, angular_speed_min=0.01, angular_speed_max=0.6,
            acceleration_max=0.5, deceleration_max=0.8, height_min=0.4, height_max=0.4,
            width=0.8, length=1.6),
        protocol_limits=ProtocolLimits(
            max_string_lens=MaxStringLens(msg_len=65536, topic_serial_len=32, topic_elem_len=32,
                                          id_len=32, id_numerical_only=False, enum_len=32,
                                          load_id_len=32),
            max_array_lens=MaxArrayLens(**{name: 20 for name in MaxArrayLens.model_fields}),
            timing=Timing(min_order_interval=0.5, min_state_interval=0.2,
                          default_state_interval=30.0, visualization_interval=0.1)),
        protocol_features=ProtocolFeatures(
            optional_parameters=[OptionalParameter(
                parameter='order.edges.direction', support=Support.REQUIRED,
                description="'left', 'right' or 'straight' at junctions")],
            agv_actions=[AgvAction(
                action_type='pick', action_description='pick a trolley',
                action_scopes=[ActionScope.NODE, ActionScope.EDGE],
                action_parameters=[AgvActionParameter(
                    key='stationType', value_data_type=ValueDataType.STRING,
                    description='where the load is', is_optional=False)],
                result_description='the loadId', blocking_types=[BlockingType.HARD])]),
        agv_geometry=AgvGeometry(
            wheel_definitions=[WheelDefinition(
                wheel_type=WheelType.DRIVE, is_active_driven=True, is_active_steered=True,
                position=WheelPosition(x=0.6, y=0.0, theta=0.0), diameter=0.25, width=0.08,
                center_displacement=0.0, constraints='steering angle within +-90 deg')],
            envelopes2d=[Envelope2d(set_name='mechanical', description='unloaded',
                                    polygon_points=[PolygonPoint(x=x, y=y) for x, y in
                                                    ((-0.8, -0.4), (0.8, -0.4), (0.8, 0.4))])],
            envelopes3d=[Envelope3d(set_name='mechanical', format='DXF', data={'layers': 1},
                                    url='https://example.org/truck.dxf', description='body')]),
        load_specification=LoadSpecification(load_positions=['front'], load_sets=[pallet]),
        vehicle_config=VehicleConfig(
            versions=[VersionInfo(key='softwareVersion', value='0.1.0')],
            network=Network(dns_servers=['192.168.1.1'], ntp_servers=['192.168.1.1'],
                            local_ip_address='192.168.1.20', netmask='255.255.255.0',
                            default_gateway='192.168.1.1')))


EXAMPLES = {'order': order_example, 'instantActions': instant_actions_example,
            'state': state_example, 'visualization': visualization_example,
            'connection': connection_example, 'factsheet': factsheet_example}


# -- walking the models' type annotations ------------------------------------------------------

def _unwrap(annotation: Any) -> list[Any]:
    """Return the types inside an annotation: through Annotated, unions, lists and dicts."""
    origin = get_origin(annotation)
    if origin is Annotated:
        return _unwrap(get_args(annotation)[0])
    if origin in (Union, types.UnionType, list, dict):
        return [t for arg in get_args(annotation) for t in _unwrap(arg)]
    return [annotation]


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    return [t for t in _unwrap(annotation) if isinstance(t, type) and issubclass(t, BaseModel)]


def _enum_in(annotation: Any) -> type[Enum] | None:
    enums = [t for t in _unwrap(annotation) if isinstance(t, type) and issubclass(t, Enum)]
    return enums[0] if enums else None


def _bounds(annotation: Any, metadata: list) -> dict[str, float]:
    """Return a field's ge/le bounds, wherever its annotation holds them (or its items')."""
    found: dict[str, float] = {}
    for item in metadata:
        if isinstance(item, FieldInfo):
            found |= _bounds(None, item.metadata)
        elif isinstance(item, annotated_types.Ge):
            found['minimum'] = item.ge
        elif isinstance(item, annotated_types.Le):
            found['maximum'] = item.le
    if get_origin(annotation) is Annotated:
        found |= _bounds(get_args(annotation)[0], list(annotation.__metadata__))
    elif get_origin(annotation) in (Union, types.UnionType, list):
        for arg in get_args(annotation):
            found |= _bounds(arg, [])
    return found


def reachable_models(cls: type[BaseModel]) -> set[type[BaseModel]]:
    seen = {cls}
    for info in cls.model_fields.values():
        for inner in _models_in(info.annotation):
            if inner not in seen:
                seen |= reachable_models(inner)
    return seen


# -- the examples validate against the official schemas ----------------------------------------

def test_schema_files_are_draft_2020_12_and_name_their_topic() -> None:
    for name in MESSAGES:
        assert schema(name)['$schema'] == 'https://json-schema.org/draft/2020-12/schema'
        assert validator(name).__class__ is Draft202012Validator
        assert schema(name)['subtopic'] == f'/{name}'


@pytest.mark.parametrize('name', list(EXAMPLES))
def test_example_validates_against_the_official_schema(name: str) -> None:
    message = EXAMPLES[name]()
    document = json.loads(to_json(message))
    assert schema_error_paths(name, document) == SCHEMA_DEFECTS_IN_EXAMPLES.get(name, set())
    assert SENT_STAMP.fullmatch(document['timestamp'])


def test_schema_defects_are_exactly_the_text_rules() -> None:
    """The listed schema failures go away when the example uses what the schema expects."""
    state = json.loads(to_json(state_example()))
    state['actionStates'][1]['actionStatus'] = 'RUNNING'
    assert schema_error_paths('state', state) == set()
    factsheet = json.loads(to_json(factsheet_example()))
    del factsheet['protocolFeatures']['agvActions'][0]['blockingTypes']
    factsheet['agvGeometry']['envelopes3d'][0]['description'] = 3
    assert schema_error_paths('factsheet', factsheet) == set()


def test_examples_set_every_field_of_every_model() -> None:
    unset = {(cls.__name__, name) for message in MESSAGES.values()
             for cls in reachable_models(message) for name in cls.model_fields}

    def visit(value: Any) -> None:
        if isinstance(value, BaseModel):
            for name in type(value).model_fields:
                if getattr(value, name) is not None:
                    unset.discard((type(value).__name__, name))
                    visit(getattr(value, name))
        elif isinstance(value, list):
            for item in value:
                visit(item)

    for build in EXAMPLES.values():
        visit(build())
    assert unset == set()


@pytest.mark.parametrize('name', list(EXAMPLES))
def test_round_trip(name: str) -> None:
    message = EXAMPLES[name]()
    text = to_json(message)
    again = parse(MESSAGES[name], text)
    assert again == message
    assert to_json(again) == text
    assert parse(MESSAGES[name], text.encode()) == message  # an MQTT payload is bytes


def test_optional_fields_are_left_out_not_null() -> None:
    document = json.loads(to_json(instant_actions_example()))
    assert 'actionDescription' not in document['actions'][0]
    assert 'actionParameters' not in document['actions'][0]
    assert 'null' not in to_json(connection_example())
    # null inside a parameter's object value is data and stays
    value = json.loads(to_json(order_example()))['nodes'][1]['actions'][0]['actionParameters']
    assert value[-1]['value'] == {'depth': 1.2, 'side': None}


def test_unknown_fields_are_kept() -> None:
    document = json.loads(to_json(order_example()))
    document['nodes'][0]['vendorHint'] = {'lane': 2}
    order = parse(Order, json.dumps(document))
    assert order.nodes[0].model_extra == {'vendorHint': {'lane': 2}}
    assert json.loads(to_json(order)) == document


# -- the standard's own example values parse ---------------------------------------------------
# Tag 2.1.0 has no example message files, and its text shows orders only as pseudocode (6.6.2);
# the examples it does give are the schemas' `examples` values and the parameters of 7.2.

DELETE = object()  # for _set: take the field out

def _example_values(name: str, node: dict, document: Any, location: tuple = ()):
    """Yield (location, value) for every `examples` value of a field the document holds."""
    node = _resolve(name, node)
    if node.get('type') == 'array' and isinstance(document, list):
        for index, item in enumerate(document):
            yield from _example_values(name, node.get('items', {}), item, (*location, index))
        return
    if not isinstance(document, dict):
        return
    for key, sub in node.get('properties', {}).items():
        if key not in document:
            continue
        for value in _resolve(name, sub).get('examples', []):
            yield (*location, key), value
        yield from _example_values(name, sub, document[key], (*location, key))


def _resolve(name: str, node: dict) -> dict:
    ref = node.get('$ref')
    return schema(name)['definitions'][ref.rsplit('/', 1)[1]] if ref else node


def _set(document: Any, location: tuple, value: Any) -> None:
    for part in location[:-1]:
        document = document[part]
    if value is DELETE:
        del document[location[-1]]
    else:
        document[location[-1]] = value


def _fields_with_examples(node: Any) -> set[str]:
    found = set()
    if isinstance(node, dict):
        found |= {key for key, sub in node.get('properties', {}).items() if 'examples' in sub}
        node = list(node.values())
    for item in node if isinstance(node, list) else []:
        found |= _fields_with_examples(item)
    return found


@pytest.mark.parametrize('name', list(EXAMPLES))
def test_the_schemas_example_values_parse(name: str) -> None:
    document = json.loads(to_json(EXAMPLES[name]()))
    tried = set()
    for location, value in _example_values(name, schema(name), document):
        changed = copy.deepcopy(document)
        _set(changed, location, value)
        parse(MESSAGES[name], json.dumps(changed))
        tried.add(location[-1])
    assert tried == _fields_with_examples(schema(name))  # every example the schema gives


def test_the_texts_action_parameters_example_parses() -> None:
    # Section 7.2's example of actionParameters.
    text = ('[{"key":"stationType", "value": "floor"}, {"key":"weight", "value": 8.5},'
            ' {"key": "loadType", "value": "pallet_eu"}]')
    action = parse(Action, '{"actionType": "someAction", "actionId": "a1", "blockingType":'
                           f' "NONE", "actionParameters": {text}}}')
    assert [(p.key, p.value) for p in action.action_parameters] == [
        ('stationType', 'floor'), ('weight', 8.5), ('loadType', 'pallet_eu')]


# -- bad input raises MessageError naming the field --------------------------------------------

ORDER_FAULTS = [  # what, where, the new value, expected (path, problem), schema rejects it too
    ('missing required field', ('nodes', 1, 'sequenceId'), DELETE,
     ('nodes[1].sequenceId', 'Field required'), True),
    ('wrong enum value', ('nodes', 1, 'actions', 0, 'blockingType'), 'MEDIUM',
     ('nodes[1].actions[0].blockingType', "Input should be 'NONE', 'SOFT' or 'HARD'"), True),
    ('enum in lower case', ('edges', 0, 'orientationType'), 'global',
     ('edges[0].orientationType', "Input should be 'GLOBAL' or 'TANGENTIAL'"), False),
    ('out of range', ('nodes', 2, 'nodePosition', 'theta'), 3.2,
     ('nodes[2].nodePosition.theta', 'less than or equal to 3.14159265359'), True),
    ('negative deviation (6.6.6)', ('nodes', 0, 'nodePosition', 'allowedDeviationTheta'), -0.1,
     ('nodes[0].nodePosition.allowedDeviationTheta', 'greater than or equal to 0'), False),
    ('wrong type in a list', ('edges', 1, 'trajectory', 'knotVector', 3), 'one',
     ('edges[1].trajectory.knotVector[3]', 'Input should be a valid number'), True),
    ('number as text', ('edges', 0, 'trajectory', 'controlPoints', 1, 'x'), '5',
     ('edges[0].trajectory.controlPoints[1].x', 'Input should be a valid number'), True),
    ('integer as text', ('headerId',), '7', ('headerId', 'Input should be a valid integer'), True),
    ('boolean as text', ('nodes', 0, 'released'), 'true',
     ('nodes[0].released', 'Input should be a valid boolean'), True),
    ('negative sequenceId', ('edges', 1, 'sequenceId'), -1,
     ('edges[1].sequenceId', 'greater than or equal to 0'), True),
    ('null for an optional field', ('nodes', 0, 'nodeDescription'), None,
     ('nodes[0].nodeDescription', 'null is not a value of this field'), True),
    ('null parameter value', ('nodes', 1, 'actions', 0, 'actionParameters', 2, 'value'), None,
     ('nodes[1].actions[0].actionParameters[2].value', 'must be an array, boolean'), True),
    ('timestamp without zone', ('timestamp',), '2024-08-19T16:09:39.12',
     ('timestamp', 'ISO 8601 UTC date-time'), False),
    ('timestamp as a number', ('timestamp',), 1724083779,
     ('timestamp', 'ISO 8601 UTC date-time'), True),
]


@pytest.mark.parametrize(('location', 'value', 'expected', 'schema_rejects'),
                         [fault[1:] for fault in ORDER_FAULTS], ids=[f[0] for f in ORDER_FAULTS])
def test_bad_order_names_the_field(location: tuple, value: Any, expected: tuple[str, str],
                                   schema_rejects: bool) -> None:
    document = json.loads(to_json(order_example()))
    _set(document, location, value)
    with pytest.raises(MessageError) as caught:
        parse(Order, json.dumps(document))
    error = caught.value
    assert error.paths == [expected[0]]
    assert expected[1] in error.problems[0][1]
    assert expected[0] in str(error)
    # The schema agrees, except where the text is stricter (the false rows).
    assert bool(schema_error_paths('order', document)) is schema_rejects


def test_malformed_json() -> None:
    for text in (to_json(order_example())[:-1], b'\xff\xfe', '', '[]', 'null'):
        with pytest.raises(MessageError) as caught:
            parse(Order, text)
        assert caught.value.paths == ['$']
    assert isinstance(caught.value, ValueError)


def test_every_problem_is_named() -> None:
    document = json.loads(to_json(instant_actions_example()))
    document['actions'][1]['blockingType'] = 'hard'
    document['actions'][1]['actionParameters'][0]['value'] = None
    del document['actions'][0]['actionId']
    document['serial_number'] = document.pop('serialNumber')  # snake_case is not on the wire
    with pytest.raises(MessageError) as caught:
        parse(InstantActions, json.dumps(document))
    assert sorted(caught.value.paths) == sorted([
        'serialNumber', 'actions[0].actionId', 'actions[1].blockingType',
        'actions[1].actionParameters[0].value'])


def test_nan_and_infinity_are_rejected() -> None:
    text = to_json(state_example())
    for bad in ('NaN', 'Infinity', '-Infinity'):
        with pytest.raises(MessageError) as caught:
            parse(State, text.replace('"omega":0.01', f'"omega":{bad}'))
        assert caught.value.paths == ['velocity.omega']


def test_a_whole_float_is_an_integer() -> None:
    # JSON Schema counts 2.0 as an integer; so do we, and send it back as 2.
    text = to_json(order_example()).replace('"degree":2', '"degree":2.0')
    assert '"degree":2.0' in text
    assert parse(Order, text).edges[1].trajectory.degree == 2
    with pytest.raises(MessageError) as caught:
        parse(Order, text.replace('"degree":2.0', '"degree":2.5'))
    assert caught.value.paths == ['edges[1].trajectory.degree']


# -- the header timestamp ----------------------------------------------------------------------

def test_timestamp_format_and_round_trip() -> None:
    stamp = datetime(2017, 4, 15, 11, 40, 3, 129999, tzinfo=UTC)
    assert format_timestamp(stamp) == '2017-04-15T11:40:03.129Z'
    message = Connection(**header(5) | {'timestamp': stamp},
                         connection_state=ConnectionState.ONLINE)
    assert json.loads(to_json(message))['timestamp'] == '2017-04-15T11:40:03.129Z'
    assert parse(Connection, to_json(message)).timestamp == stamp.replace(microsecond=129000)
    document = json.loads(to_json(message))
    for text, expected in (('2017-04-15T11:40:03.12Z', 120000),  # the standard's form, 6.4
                           ('2017-04-15T13:40:03.12+02:00', 120000),
                           ('2017-04-15T11:40:03.123456789Z', 123000),
                           ('2017-04-15T11:40:03Z', 0)):
        document['timestamp'] = text
        parsed = parse(Connection, json.dumps(document)).timestamp
        assert parsed == datetime(2017, 4, 15, 11, 40, 3, expected, tzinfo=UTC)
        assert parsed.tzinfo is UTC
    eastern = datetime(2017, 4, 15, 7, 40, 3, tzinfo=timezone(timedelta(hours=-4)))
    assert format_timestamp(eastern) == '2017-04-15T11:40:03.000Z'
    assert SENT_STAMP.fullmatch(format_timestamp(now()))
    with pytest.raises(ValueError, match='time zone'):
        Connection(**header(5) | {'timestamp': datetime(2017, 4, 15)},
                   connection_state=ConnectionState.ONLINE)


# -- every field of the schemas is in the models -----------------------------------------------

def compare(name: str, node: dict, cls: type[BaseModel], path: str, found: dict) -> None:
    """Walk a schema object and its model together, noting every difference in `found`."""
    fields = {info.alias or key: info for key, info in cls.model_fields.items()}
    properties = node.get('properties', {})
    found['missing'] |= {f'{path}{key}' for key in properties if key not in fields}
    found['extra'] |= {f'{path}{key}' for key in fields if key not in properties}
    required = {key for key, info in fields.items() if info.is_required()}
    found['required'] |= {f'{path}{key}' for key in required ^ set(node.get('required', []))}
    for key, sub in properties.items():
        if key not in fields:
            continue
        info, sub = fields[key], _resolve(name, sub)
        items = _resolve(name, sub.get('items', {})) if sub.get('type') == 'array' else {}
        enum = _enum_in(info.annotation)
        wire_enum = sub.get('enum', items.get('enum'))
        if {m.value for m in enum or []} != set(wire_enum or []):
            found['enum'].add(f'{path}{key}')
        bounds = _bounds(info.annotation, info.metadata)
        for limit in ('minimum', 'maximum'):
            wire = sub.get(limit, items.get(limit))
            if wire is not None and bounds.get(limit) != wire:
                found['bounds'].add(f'{path}{key}.{limit}')
        inner = items if items else sub
        if 'properties' in inner:
            (model,) = _models_in(info.annotation)
            compare(name, inner, model, f'{path}{key}{"[]" if items else ""}.', found)


# What the models have beyond the schemas, each from the standard's text (or, for shared objects,
# from the same object elsewhere in the text).
EXPECTED_DIFFERENCES = {
    'order': {'enum': {'edges[].orientationType'},  # the schema gives no enum; 6.6.6 does
              'bounds': {'nodes[].nodePosition.allowedDeviationTheta.minimum'}},  # 0 in 6.6.6
    'instantActions': {},
    'state': {
        'enum': {'actionStates[].actionStatus'},  # 'PAUSED', 6.11
        # nodeStates carry the order's nodePosition (6.10.6), which the schema gives in part
        'extra': {'nodeStates[].nodePosition.allowedDeviationXY',
                  'nodeStates[].nodePosition.allowedDeviationTheta',
                  'nodeStates[].nodePosition.mapDescription'}},
    'visualization': {
        'extra': {'agvPosition.mapDescription'},  # the state's agvPosition (6.13)
        'required': {'headerId', 'timestamp', 'version', 'manufacturer', 'serialNumber'}},  # 6.4
    'connection': {},
    'factsheet': {
        'extra': {'physicalParameters.angularSpeedMin', 'physicalParameters.angularSpeedMax'},
        'required': {'headerId', 'timestamp', 'physicalParameters.heightMin'}},
}


@pytest.mark.parametrize('name', list(MESSAGES))
def test_models_have_every_schema_field(name: str) -> None:
    found: dict[str, set[str]] = {k: set() for k in ('missing', 'extra', 'required', 'enum',
                                                     'bounds')}
    compare(name, schema(name), MESSAGES[name], '', found)
    expected = {k: EXPECTED_DIFFERENCES[name].get(k, set()) for k in found}
    assert found == expected


# -- topics ------------------------------------------------------------------------------------

def test_topic_names() -> None:
    assert topic('KIT', '0001', 'order') == 'uagv/v2/KIT/0001/order'  # 6.3's example
    assert topic('Cableform', 'truck-1.a:b_c', 'instantActions', interface='plant') == \
        'plant/v2/Cableform/truck-1.a:b_c/instantActions'
    for manufacturer, serial, name in (('KIT', '0001', 'orders'), ('KIT', 'a/b', 'state'),
                                       ('', '0001', 'state'), ('KIT', '+', 'state'),
                                       ('K#T', '0001', 'state'), ('$SYS', '0001', 'state')):
        with pytest.raises(ValueError):
            topic(manufacturer, serial, name)


def test_topic_table() -> None:
    assert set(TOPICS) == set(MESSAGES)
    for name, entry in TOPICS.items():
        assert entry.message is MESSAGES[name]
        assert entry.publisher == (MASTER_CONTROL if name in ('order', 'instantActions')
                                   else AGV)  # 6.5
    assert {n: (t.qos, t.retain) for n, t in TOPICS.items()} == {
        'order': (0, False), 'instantActions': (0, False), 'state': (0, False),
        'visualization': (0, False), 'connection': (1, True), 'factsheet': (0, True)}
