"""The VDA 5050 factsheet (6.15) of our truck: the 1983 Cableform Electruk as the package has it.

Every figure is read from where the package keeps it: the vehicle's geometry from the world's
Electruk parameters, its speeds from the executive's duty demands through closed-loop
traction's duty-to-speed map, its acceleration limits from that loop's ramp, the node actions
from the task verbs the bridge turns them into (agv_nodes.vda5050.order_tasks). What the
package does not model (the truck's height, the wheels' widths, its rated load) is a named
constant below marked as an assumption; the outline is the world's (assumed there too: the
trucks of a fleet touch with it).

The truck's reference point (6.6.6's vehicle coordinate system: x forward, y left) is the front
axle centre: the guide-wire coils hold it on the wire and the marker sensor reads a card abreast
of it (agv_nodes.world.vehicles.Electruk.sensor_point), so it is the point that stands at a
node of the track graph (agv_nodes.fleet.track_graph.TrackNode).
"""

from __future__ import annotations

from datetime import datetime
import math

from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.markers import SLOW1
from agv_nodes.settings import parameters
from agv_nodes.traction.settings import TractionParams
from agv_nodes.vda5050 import VERSION
from agv_nodes.vda5050.common import BlockingType
from agv_nodes.vda5050.common import now as utc_now
from agv_nodes.vda5050.factsheet import (
    ActionScope,
    AgvAction,
    AgvActionParameter,
    AgvClass,
    AgvGeometry,
    AgvKinematic,
    Envelope2d,
    Factsheet,
    LoadSpecification,
    LocalizationType,
    MaxArrayLens,
    MaxStringLens,
    NavigationType,
    OptionalParameter,
    PhysicalParameters,
    PolygonPoint,
    ProtocolFeatures,
    ProtocolLimits,
    Support,
    Timing,
    TypeSpecification,
    ValueDataType,
    WheelDefinition,
    WheelPosition,
    WheelType,
)
from agv_nodes.vda5050.order_tasks import ACTIONS_PER_NODE, TASK_VERBS, WAIT_MAX, WAIT_PARAMETER
from agv_nodes.world.settings import WorldParams

SERIES_NAME = 'Cableform Electruk'

# Assumptions: the package simulates none of these, and Baker 1983 gives none of them.
# kg on the truck: the thesis's figure, which the world has only in electruk.payload's text
MAX_LOAD_MASS = 1000.0
HEIGHT = 0.75  # m, floor to the top of the conveyors, unloaded
FRONT_WHEEL_DIAMETER = 0.3  # m; the bicycle model needs no front wheel size
WHEEL_WIDTH = 0.08  # m, every wheel

# The bridge sends state at most this often (s).
MIN_STATE_INTERVAL = 0.1
# Zero is "no limit" (6.15.1, protocolLimits): the bridge queues every order the broker delivers
# and takes them all on its next poll, so no order is lost however closely they follow.
MIN_ORDER_INTERVAL = 0.0
# 6.10: state at the latest every 30 s; the bridge's state_interval may make it shorter.
DEFAULT_STATE_INTERVAL = 30.0

# The node action types the bridge turns into tasks, and the instant actions it takes.
ACTIONS = frozenset(TASK_VERBS)
INSTANT_ACTIONS = frozenset({'cancelOrder', 'initPosition', 'startPause', 'stopPause',
                             'stateRequest', 'factsheetRequest'})

_CONVEYOR_CHOICE = 'start_loaded'  # the world parameter whose choices name the conveyors


def load_positions() -> list[str]:
    """Return the truck's conveyors, first then second, as the world's parameters name them."""
    spec = next(p.spec for p in parameters(WorldParams) if p.name == _CONVEYOR_CHOICE)
    return list(spec.choices)


def demand_speed(duty: float, traction: TractionParams | None = None) -> float:
    """Return the speed (m/s) closed-loop traction holds for a demand of `duty` %."""
    t = traction or TractionParams()
    return max(0.0, abs(duty) - t.dead_band) * t.v_per_percent


def _node_action(action_type: str, description: str, result: str,
                 action_parameters: list[AgvActionParameter] | None = None) -> AgvAction:
    # Every node action is a task that ends with the truck standing at a stop marker: nothing
    # else runs and the truck does not drive while it acts.
    return AgvAction(action_type=action_type, action_description=description,
                     action_scopes=[ActionScope.NODE], action_parameters=action_parameters,
                     result_description=result, blocking_types=[BlockingType.HARD])


def _agv_actions() -> list[AgvAction]:
    # A station's first stop marker lines up the first conveyor, its second the second.
    conveyor = ('the conveyor the node lines up (the stop marker chooses it: action parameters '
                'are not read)')
    node = {
        'pick': _node_action(
            'pick', f'stop at the node, a stop marker, and load from the station onto {conveyor}',
            'the load is on the conveyor'),
        'drop': _node_action(
            'drop', f'stop at the node, a stop marker, and unload from {conveyor} to the station',
            'the load is on the station'),
        'wait': _node_action(
            'wait', 'stop at the node, a stop marker, and stand there for a while',
            'the time has passed',
            [AgvActionParameter(key=WAIT_PARAMETER, value_data_type=ValueDataType.INTEGER,
                                description=f'whole seconds, 0-{WAIT_MAX}',
                                is_optional=False)]),
    }
    instant = [
        # cancelOrder is the truck's abort: an emergency stop where it is, the queue dropped.
        AgvAction(action_type='cancelOrder', action_scopes=[ActionScope.INSTANT],
                  action_description='emergency stop where the truck is; the order and its '
                  'queued tasks are dropped', blocking_types=[BlockingType.HARD]),
        AgvAction(action_type='initPosition', action_scopes=[ActionScope.INSTANT],
                  action_description='the stop marker node the truck stands at (it knows '
                  'where it is only from the markers it passes)',
                  action_parameters=[AgvActionParameter(
                      key='lastNodeId', value_data_type=ValueDataType.STRING,
                      description='a stop marker node of the track graph',
                      is_optional=False)],
                  blocking_types=[BlockingType.HARD]),
        # The task language's pause and resume: traction ramps to rest, the task is kept.
        AgvAction(action_type='startPause', action_scopes=[ActionScope.INSTANT],
                  action_description='come to rest where the truck is by a controlled stop; '
                  'the order is kept, and a load or wait in hand goes on',
                  result_description='FINISHED once the truck is at rest (paused true)',
                  blocking_types=[BlockingType.HARD]),
        AgvAction(action_type='stopPause', action_scopes=[ActionScope.INSTANT],
                  action_description='drive on with the order as if never paused',
                  result_description='FINISHED once the truck drives as its task asks '
                  '(paused false)',
                  blocking_types=[BlockingType.HARD]),
        AgvAction(action_type='stateRequest', action_scopes=[ActionScope.INSTANT],
                  action_description='send a state message now',
                  blocking_types=[BlockingType.NONE]),
        AgvAction(action_type='factsheetRequest', action_scopes=[ActionScope.INSTANT],
                  action_description='send this factsheet now',
                  blocking_types=[BlockingType.NONE]),
    ]
    return [node[action_type] for action_type in TASK_VERBS] + instant


def _geometry(world: WorldParams) -> tuple[AgvGeometry, float]:
    """Return the wheels and outline (front axle centre as origin) and the truck's length."""
    e = world.electruk
    front, rear = e.front_overhang, -(e.wheelbase + e.rear_overhang)
    wheels = [
        # A plain wheel on a steered fork: not a drive unit, not a castor, so FIXED, with the
        # steering said by isActiveSteered.
        WheelDefinition(wheel_type=WheelType.FIXED, is_active_driven=False,
                        is_active_steered=True, position=WheelPosition(x=0.0, y=0.0, theta=0.0),
                        diameter=FRONT_WHEEL_DIAMETER, width=WHEEL_WIDTH,
                        constraints=f'steered within +-{math.degrees(e.max_steer):.0f} deg at '
                        f'up to {math.degrees(e.steer_rate):.0f} deg/s'),
        *(WheelDefinition(wheel_type=WheelType.DRIVE, is_active_driven=True,
                          is_active_steered=False,
                          position=WheelPosition(x=-e.wheelbase, y=side * e.track / 2.0,
                                                 theta=0.0),
                          diameter=2.0 * e.wheel_radius, width=WHEEL_WIDTH,
                          constraints='driven with the other rear wheel by two motors in parallel')
          for side in (1.0, -1.0)),
    ]
    half = e.width / 2.0
    outline = Envelope2d(set_name='mechanical', description='the body, loaded or not',
                         polygon_points=[PolygonPoint(x=x, y=y) for x, y in (
                             (rear, -half), (front, -half), (front, half), (rear, half))])
    return AgvGeometry(wheel_definitions=wheels, envelopes2d=[outline]), front - rear


# The optional fields of state (6.10.6) the bridge fills (agv_nodes.vda5050.bridge); what it
# leaves out (zoneSetId, maps, batteryState's voltage, health and reach) is not listed.
STATE_FIELDS = [
    OptionalParameter(parameter='state.agvPosition', support=Support.SUPPORTED,
                      description='the last marker card read and dead reckoning from the wheel '
                      'counters since; deviationRange grows with the distance driven'),
    OptionalParameter(parameter='state.velocity', support=Support.SUPPORTED,
                      description='from the wheel counters'),
    OptionalParameter(parameter='state.loads', support=Support.SUPPORTED,
                      description="the two conveyors' load sensors: loadPosition only"),
    OptionalParameter(parameter='state.distanceSinceLastNode', support=Support.SUPPORTED,
                      description='the wheel counters since the last card read'),
    OptionalParameter(parameter='visualization', support=Support.SUPPORTED,
                      description='agvPosition and velocity, once a second'),
]


def truck_factsheet(manufacturer: str, serial_number: str, header_id: int,
                    timestamp: datetime | None = None, *,
                    state_interval: float = DEFAULT_STATE_INTERVAL) -> Factsheet:
    """Return the factsheet of one truck; `state_interval` is the bridge's (at most 30 s)."""
    world, executive, traction = WorldParams(), ExecutiveParams(), TractionParams()
    geometry, length = _geometry(world)
    speed_max = demand_speed(executive.cruise_demand, traction)
    positions = load_positions()
    # The body rides lower as it is loaded (the world's ride_height_per_tonne).
    height_min = HEIGHT - world.ride_height_per_tonne * MAX_LOAD_MASS / 1000.0
    return Factsheet(
        header_id=header_id, timestamp=timestamp or utc_now(), version=VERSION,
        manufacturer=manufacturer, serial_number=serial_number,
        type_specification=TypeSpecification(
            series_name=SERIES_NAME,
            series_description='wire-guided tricycle of Baker 1983: a steered front wheel, '
            'driven rear wheels, two conveyors on top; stops at location and stop markers '
            'read by an optical sensor',
            # 6.15.1: THREEWHEEL is a three-wheel vehicle "or with similar kinematics": one
            # steered wheel ahead of a driven axle turns about a point on the rear axle's line,
            # which neither DIFF nor OMNI can.
            agv_kinematic=AgvKinematic.THREEWHEEL,
            agv_class=AgvClass.CONVEYOR,
            max_load_mass=MAX_LOAD_MASS,
            # The truck knows where it is from marker cards beside the wire: 2 x 4 black and
            # white elements that an infrared photodiode array reads as a code (Baker 1983,
            # 4.3-5.1). Of the standard's kinds that is a printed optical code read off a card:
            # DMC, not RFID (radio), SPOT or GRID (magnets), REFLECTOR or NATURAL (lasers).
            localization_types=[LocalizationType.DMC],
            navigation_types=[NavigationType.PHYSICAL_LINE_GUIDED]),
        physical_parameters=PhysicalParameters(
            # The slowest it drives is the positioning creep onto a stop marker.
            speed_min=demand_speed(SLOW1, traction),
            speed_max=speed_max,
            # The tightest turn at top speed; it cannot turn on the spot.
            angular_speed_max=speed_max * math.tan(world.electruk.max_steer)
            / world.electruk.wheelbase,
            acceleration_max=traction.max_accel,
            deceleration_max=traction.max_decel,
            height_min=height_min, height_max=HEIGHT, width=world.electruk.width,
            length=length),
        protocol_limits=ProtocolLimits(
            max_string_lens=MaxStringLens(),
            # Edge actions are refused too, but 0 would say "no limit": the agvActions say it
            # by giving no action the EDGE scope.
            max_array_lens=MaxArrayLens(node_actions=ACTIONS_PER_NODE,
                                        state_loads=len(positions)),
            timing=Timing(min_order_interval=MIN_ORDER_INTERVAL,
                          min_state_interval=MIN_STATE_INTERVAL,
                          default_state_interval=state_interval)),
        protocol_features=ProtocolFeatures(optional_parameters=STATE_FIELDS,
                                           agv_actions=_agv_actions()),
        agv_geometry=geometry,
        load_specification=LoadSpecification(load_positions=positions))
