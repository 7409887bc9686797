"""Where the truck is, as it could know it: the last card it read and its wheels since.

The 1983 truck knows its place only at the markers it reads (Baker 1983, 4.4: location markers
serve as landmarks; navigation's odometry is the driven wheels' mean travel, 6.3.3). The bridge
tells the master the same (VDA 5050 6.10.6): lastNodeId is a node the truck has read, and
agvPosition is the read node's pose on the track graph (the wire abreast of the card) carried on
by dead reckoning from the wheel counters (agv_nodes.view.odometry), with a deviationRange that
grows with the distance driven since and a localizationScore that falls as it grows. Before the
truck has read a card (or been told by initPosition where it stands) positionInitialized is
false.

A card read is placed on the graph here: a location card by its identity, a stop marker's
centre (which the sensor reports as one identity, EDIM, for every stop marker) as the next stop
marker on the way. A read less than half an edge's length from the node before it is the card
the truck has just stood on, seen again as it leaves, and is not a new node.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from agv_nodes.fleet.track_graph import TrackGraph, TrackNode
from agv_nodes.odometry import counter_step
from agv_nodes.vda5050.state import AgvPosition, Velocity
from agv_nodes.view.odometry import PlanarPose, WheelDeadReckoning

# How far from the card's place the sensor is when a card has been read: a card met straight on
# is read within 5 mm of it, but one met coming off a curve skewed to the wire is read up to
# 0.10 m past it (L1 of demo_1983: 0.102 m), and a stop ends up to 0.04 m past its marker
# (W1.1: 0.041 m), measured against the world's ground truth (test_vda5050_truck_state.py).
MARKER_DEVIATION = 0.12  # m
# Dead reckoning's error per metre driven since the card: wheel slip, the counters' mm rounding
# and the heading integrated from the wheels' difference. Measured on the demo drive below
# 0.01 m per metre after the card; the same test holds every position sent within the range.
DRIFT_PER_METRE = 0.02
# The share of an edge's length the truck must have driven before a card read is the edge's end.
REREAD_FRACTION = 0.5


@dataclass(frozen=True)
class TractionFacts:
    """What traction reports that the state shows (traction_status, Baker 1983 6.3.1).

    e_stop: an emergency stop button pressed on the truck (eStop MANUAL: acknowledged on the
    truck; no record of the 1983 truck carries one); radio_stop: the radio stop input, the
    remote emergency stop (eStop REMOTE); bumper: pressed by another truck or an obstacle (the
    protective field of 6.10.6: fieldViolation); manual: the truck driven by hand (REF from the
    command byte), not by its executive (operatingMode MANUAL).
    """

    e_stop: bool = False
    radio_stop: bool = False
    bumper: bool = False
    manual: bool = False


class Whereabouts:
    """The last node read, the pose since it, and the placing of card reads on the graph."""

    def __init__(self, graph: TrackGraph, track: float, wheelbase: float, map_id: str) -> None:
        self.graph = graph
        self.wheelbase = wheelbase  # m from the driven axle to the sensor (the front axle)
        self.map_id = map_id
        self.node: TrackNode | None = None  # the last node read (or set by initPosition)
        self.since = 0.0  # m driven since that node
        self._dead = WheelDeadReckoning(track)
        self._counters: tuple[int, int] | None = None
        self.unplaced = 0  # card reads that were no node ahead (counted, shown in diagnostics)

    @property
    def initialized(self) -> bool:
        """True once the truck has read a card or been told where it stands."""
        return self.node is not None

    def at_node(self, node_id: str) -> None:
        """Take `node_id` as the place the truck is at now (read, reached, or initPosition)."""
        node = self.graph.nodes.get(node_id)
        if node is None or (self.node is node and self.since < MARKER_DEVIATION):
            return
        p = self._dead.pose  # the driven axle's centre, a wheelbase behind the sensor
        if self.node is None:
            p.heading = node.theta  # the wire's; from then on the wheels' (a truck coming off
            # a curve reads the card skewed to the wire by as much as 0.13 rad)
        self.node, self.since = node, 0.0
        p.x = node.x - self.wheelbase * math.cos(p.heading)
        p.y = node.y - self.wheelbase * math.sin(p.heading)

    def on_wheels(self, left_mm: int, right_mm: int, left_speed: int, right_speed: int) -> None:
        """Take one wheel_odometry reading (wrapping mm counters, mm/s)."""
        if self._counters is not None:
            dl = counter_step(self._counters[0], left_mm)
            dr = counter_step(self._counters[1], right_mm)
            self.since += abs(dl + dr) / 2000.0
        self._counters = (left_mm, right_mm)
        self._dead.update({'left_distance': left_mm, 'right_distance': right_mm,
                           'left_speed': left_speed, 'right_speed': right_speed})

    def place(self, location: int | None, ahead: list[str]) -> str | None:
        """Return the node a card read is, or None (not a node ahead: counted as unplaced).

        `location` is a location card's identity, None a stop marker's centre; `ahead` the
        order's nodes still to traverse, in order (empty without an order). With an order the
        read is the first of them that such a card can be (a stop marker's read passes no
        location card); without one, a successor on the graph of the node last read, or before
        any, the location card of that identity (the layout's first card where it is one).
        """
        if ahead:
            candidates = ahead
        elif self.node is not None:
            candidates = [e.end for e in self.graph.successors(self.node.id)]
        else:
            candidates = [n.id for n in self.graph.nodes.values() if self._is(n.id, location)]
            if self.graph.start in candidates:
                candidates = [self.graph.start]
            candidates = candidates[:1] if location is not None else []
        for node_id in candidates:
            if self._is(node_id, location):
                if self.node is not None and node_id == self.node.id:
                    return None  # the card the executive has just reported (a location), or
                    # the one the truck stood on, read again as it leaves
                if self._too_soon(node_id):
                    return None  # the card just stood on, read as the next one's edge begins
                return node_id
            if ahead and location is None and self.graph.nodes[node_id].kind == 'location':
                break  # a stop marker's read never passes a location card not read
        self.unplaced += 1
        return None

    def _is(self, node_id: str, location: int | None) -> bool:
        node = self.graph.nodes.get(node_id)
        if node is None:
            return False
        if location is None:
            return node.kind == 'stop'
        return node.kind == 'location' and node.location == location

    def _too_soon(self, node_id: str) -> bool:
        if self.node is None:
            return False
        edge = self.graph.edge(self.node.id, node_id)
        return edge is not None and self.since < REREAD_FRACTION * edge.length

    @property
    def deviation(self) -> float:
        """The pose's deviation range, m: the card's, and the drift since."""
        return MARKER_DEVIATION + DRIFT_PER_METRE * self.since

    def position(self) -> AgvPosition:
        """Return agvPosition (6.10.6) on the layout's map (the world frame).

        The truck's reference point is the front axle's centre, where the sensor reads the
        cards (the factsheet's origin of the truck's geometry).
        """
        dead: PlanarPose = self._dead.pose
        p = PlanarPose(x=dead.x + self.wheelbase * math.cos(dead.heading),
                       y=dead.y + self.wheelbase * math.sin(dead.heading), heading=dead.heading)
        if self.node is None:
            return AgvPosition(position_initialized=False, localization_score=0.0,
                               x=p.x, y=p.y, theta=_wrap(p.heading), map_id=self.map_id,
                               map_description='dead reckoning from power-up: no card read yet')
        return AgvPosition(position_initialized=True,
                           localization_score=MARKER_DEVIATION / self.deviation,
                           deviation_range=self.deviation, x=p.x, y=p.y,
                           theta=_wrap(p.heading), map_id=self.map_id,
                           map_description=f'{self.since:.2f} m of dead reckoning since '
                           f'{self.node.id}')

    def velocity(self) -> Velocity:
        """Return the velocity in the truck's frame (6.10.6): along its heading, and yaw."""
        p = self._dead.pose
        return Velocity(vx=p.speed, vy=0.0, omega=p.yaw_rate)


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))
