"""Our truck's VDA 5050 factsheet (agv_nodes.vda5050.truck_factsheet).

It must be a valid message (our models and the standard's 2.1.0 JSON schema), and every figure
must be the package's: the world's Electruk, the executive's demands through traction's map, the
bridge's task verbs. The world's vehicle model, loaded to the rated mass, must be able to do what
the factsheet says.
"""

from dataclasses import replace
from datetime import UTC, datetime
import functools
import json
import math
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator
from jsonschema.validators import validator_for
import pytest

from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.markers import SLOW1
from agv_nodes.traction.settings import TractionParams
from agv_nodes.vda5050 import VERSION
from agv_nodes.vda5050.codec import field_path, parse, to_json
from agv_nodes.vda5050.common import BlockingType
from agv_nodes.vda5050.factsheet import (
    ActionScope,
    AgvClass,
    AgvKinematic,
    Factsheet,
    LocalizationType,
    NavigationType,
    ValueDataType,
    WheelType,
)
from agv_nodes.vda5050.order_tasks import TASK_VERBS, WAIT_MAX, WAIT_PARAMETER
from agv_nodes.vda5050.truck_factsheet import (
    ACTIONS,
    HEIGHT,
    INSTANT_ACTIONS,
    MAX_LOAD_MASS,
    MIN_STATE_INTERVAL,
    SERIES_NAME,
    truck_factsheet,
)
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.vehicles import Electruk

pytestmark = pytest.mark.timeout(60)

SCHEMA = Path(__file__).resolve().parent / 'data' / 'vda5050_2.1.0' / 'factsheet.schema'
STAMP = datetime(2024, 8, 19, 16, 9, 39, 120000, tzinfo=UTC)


@functools.cache
def validator() -> Draft202012Validator:
    schema = json.loads(SCHEMA.read_text(encoding='utf-8'))
    cls = validator_for(schema)  # the draft the schema's $schema names
    cls.check_schema(schema)
    return cls(schema)


def schema_error_paths(document: Any) -> set[str]:
    return {field_path(tuple(e.absolute_path)) for e in validator().iter_errors(document)}


@pytest.fixture(scope='module')
def sheet() -> Factsheet:
    return truck_factsheet('agv_nodes', 'agv1', 7, STAMP)


def actions_of(sheet: Factsheet) -> dict[str, Any]:
    return {a.action_type: a for a in sheet.protocol_features.agv_actions}


def demand_speed(duty: int) -> float:
    """Return the speed closed-loop traction holds for a duty demand (traction/core.py)."""
    t = TractionParams()
    return (duty - t.dead_band) * t.v_per_percent


# -- a valid message ---------------------------------------------------------------------------

def test_round_trip(sheet: Factsheet) -> None:
    assert parse(Factsheet, to_json(sheet)) == sheet


def test_validates_against_the_official_schema(sheet: Factsheet) -> None:
    """Only the schema's own defect fails: it puts the blockingTypes enum on the array."""
    document = json.loads(to_json(sheet))
    n = len(document['protocolFeatures']['agvActions'])
    assert schema_error_paths(document) == {
        f'protocolFeatures.agvActions[{i}].blockingTypes' for i in range(n)}
    for action in document['protocolFeatures']['agvActions']:
        del action['blockingTypes']
    assert schema_error_paths(document) == set()


def test_header(sheet: Factsheet) -> None:
    document = json.loads(to_json(sheet))
    assert (document['headerId'], document['manufacturer'], document['serialNumber'],
            document['version']) == (7, 'agv_nodes', 'agv1', VERSION)
    assert document['timestamp'] == '2024-08-19T16:09:39.120Z'


def test_without_a_timestamp_it_is_stamped_now() -> None:
    before = datetime.now(UTC).replace(microsecond=0)
    stamped = truck_factsheet('m', 's', 0).timestamp
    assert before <= stamped <= datetime.now(UTC)


def test_deterministic() -> None:
    assert to_json(truck_factsheet('m', 's', 3, STAMP)) == \
        to_json(truck_factsheet('m', 's', 3, STAMP))


# -- the truck's figures -----------------------------------------------------------------------

def test_type_specification(sheet: Factsheet) -> None:
    t = sheet.type_specification
    assert t.series_name == SERIES_NAME == 'Cableform Electruk'
    assert t.agv_kinematic is AgvKinematic.THREEWHEEL
    assert t.agv_class is AgvClass.CONVEYOR
    assert t.max_load_mass == MAX_LOAD_MASS
    assert t.localization_types == [LocalizationType.DMC]
    assert t.navigation_types == [NavigationType.PHYSICAL_LINE_GUIDED]


def test_speeds_and_accelerations_are_the_packages(sheet: Factsheet) -> None:
    p, traction, e = sheet.physical_parameters, TractionParams(), WorldParams().electruk
    assert p.speed_max == pytest.approx(demand_speed(ExecutiveParams().cruise_demand))
    assert p.speed_min == pytest.approx(demand_speed(SLOW1))
    assert 0.0 < p.speed_min < p.speed_max
    assert p.acceleration_max == traction.max_accel
    assert p.deceleration_max == traction.max_decel
    assert p.angular_speed_max == pytest.approx(p.speed_max * math.tan(e.max_steer)
                                                / e.wheelbase)
    assert p.angular_speed_min is None


def test_sizes(sheet: Factsheet) -> None:
    p, world = sheet.physical_parameters, WorldParams()
    e = world.electruk
    assert p.length == pytest.approx(e.wheelbase + e.front_overhang + e.rear_overhang)
    assert p.width == e.width
    assert p.height_max == HEIGHT
    assert p.height_min == pytest.approx(HEIGHT - world.ride_height_per_tonne
                                         * MAX_LOAD_MASS / 1000.0)


def test_wheels_are_the_worlds_and_inside_the_outline(sheet: Factsheet) -> None:
    e = WorldParams().electruk
    wheels = sheet.agv_geometry.wheel_definitions
    front = [w for w in wheels if w.is_active_steered]
    rear = [w for w in wheels if w.is_active_driven]
    assert len(wheels) == 3 and len(front) == 1 and len(rear) == 2
    assert front[0].wheel_type is WheelType.FIXED and not front[0].is_active_driven
    assert (front[0].position.x, front[0].position.y) == (0.0, 0.0)  # the reference point
    assert f'+-{math.degrees(e.max_steer):.0f} deg' in front[0].constraints
    for w in rear:
        assert w.wheel_type is WheelType.DRIVE and not w.is_active_steered
        assert w.position.x == pytest.approx(-e.wheelbase)
        assert w.diameter == pytest.approx(2.0 * e.wheel_radius)
    assert sorted(w.position.y for w in rear) == pytest.approx([-e.track / 2, e.track / 2])
    (outline,) = sheet.agv_geometry.envelopes2d
    xs = [q.x for q in outline.polygon_points]
    ys = [q.y for q in outline.polygon_points]
    assert max(xs) - min(xs) == pytest.approx(sheet.physical_parameters.length)
    assert max(ys) - min(ys) == pytest.approx(sheet.physical_parameters.width)
    for w in wheels:
        x, y, r = w.position.x, w.position.y, w.diameter / 2
        assert min(xs) <= x - r and x + r <= max(xs)
        assert min(ys) <= y - w.width / 2 and y + w.width / 2 <= max(ys)


def test_marker_lens_is_on_the_body(sheet: Factsheet) -> None:
    """The layouts put the lens this far right of the reference point: at most the side."""
    lateral = load_layout(layout_path('demo_1983')).sensor_lateral
    assert lateral <= sheet.physical_parameters.width / 2


def _peak_acceleration(forward: bool, speed: float) -> float:
    """Largest |dv/dt| of the world's Electruk at the rated load, full duty and field."""
    p = replace(WorldParams().electruk, payload=MAX_LOAD_MASS)
    traction = TractionParams()
    truck = Electruk(p)
    truck.state.speed = speed
    field = traction.field_duty / 100.0
    truck.flux = field if forward else -field  # the field already built up (or flipped)
    truck.set_drive(traction.max_duty / 100.0, field, forward, True, True, True)
    dt, peak = 0.001, 0.0
    for _ in range(3000):
        before = truck.state.speed
        truck.step(dt)
        if not forward and truck.state.speed <= 0.0:
            break
        peak = max(peak, abs(truck.state.speed - before) / dt)
    return peak


def test_the_world_truck_can_do_it_at_the_rated_load(sheet: Factsheet) -> None:
    """The factsheet's accelerationMax and decelerationMax are "with maximum load" (6.15.1)."""
    p = sheet.physical_parameters
    assert _peak_acceleration(True, 0.0) >= p.acceleration_max
    assert _peak_acceleration(False, p.speed_max) >= p.deceleration_max


# -- what the bridge takes ---------------------------------------------------------------------

def test_action_types_are_the_constants(sheet: Factsheet) -> None:
    actions = actions_of(sheet)
    node = {t for t, a in actions.items() if ActionScope.NODE in a.action_scopes}
    instant = {t for t, a in actions.items() if ActionScope.INSTANT in a.action_scopes}
    assert node == ACTIONS == set(TASK_VERBS) == {'pick', 'drop', 'wait'}
    assert instant == INSTANT_ACTIONS == {'cancelOrder', 'initPosition', 'startPause',
                                          'stopPause', 'stateRequest', 'factsheetRequest'}
    assert set(actions) == ACTIONS | INSTANT_ACTIONS
    assert len(sheet.protocol_features.agv_actions) == len(actions)  # each listed once


def test_scopes_and_blocking(sheet: Factsheet) -> None:
    for action_type, action in actions_of(sheet).items():
        if action_type in ACTIONS:
            assert action.action_scopes == [ActionScope.NODE]
            assert action.blocking_types == [BlockingType.HARD]
        else:
            assert action.action_scopes == [ActionScope.INSTANT]
        assert ActionScope.EDGE not in action.action_scopes


def test_parameters(sheet: Factsheet) -> None:
    actions = actions_of(sheet)
    (duration,) = actions['wait'].action_parameters
    assert duration.key == WAIT_PARAMETER == 'duration'
    assert duration.value_data_type is ValueDataType.INTEGER
    assert duration.is_optional is False
    assert f'0-{WAIT_MAX}' in duration.description
    (node,) = actions['initPosition'].action_parameters
    assert (node.key, node.value_data_type, node.is_optional) == (
        'lastNodeId', ValueDataType.STRING, False)
    for action_type, action in actions.items():
        if action_type not in ('wait', 'initPosition'):
            assert action.action_parameters is None
    # the state's optional fields the bridge fills (6.10.6), and visualization (6.13)
    assert {(o.parameter, o.support) for o in sheet.protocol_features.optional_parameters} == {
        ('state.agvPosition', 'SUPPORTED'), ('state.velocity', 'SUPPORTED'),
        ('state.loads', 'SUPPORTED'), ('state.distanceSinceLastNode', 'SUPPORTED'),
        ('visualization', 'SUPPORTED')}


def test_protocol_limits(sheet: Factsheet) -> None:
    limits = sheet.protocol_limits
    assert json.loads(to_json(limits.max_string_lens)) == {}
    assert json.loads(to_json(limits.max_array_lens)) == {'node.actions': 1, 'state.loads': 2}
    timing = limits.timing
    assert timing.min_state_interval == MIN_STATE_INTERVAL == 0.1
    assert timing.min_order_interval == 0.0
    assert timing.default_state_interval == 30.0
    assert timing.visualization_interval is None
    assert truck_factsheet('m', 's', 0, STAMP, state_interval=5.0) \
        .protocol_limits.timing.default_state_interval == 5.0


def test_load_positions_are_the_two_conveyors(sheet: Factsheet) -> None:
    load = sheet.load_specification
    assert load.load_positions == ['first', 'second']
    assert load.load_sets is None
    assert sheet.protocol_limits.max_array_lens.state_loads == len(load.load_positions)
