"""The messages a master control sends a truck: order (6.6) and instantActions (6.9).

An order is a graph of nodes and edges, each with its sequenceId; the released ones are the
base, the rest the horizon (6.6.1). The bridge parses these with codec.parse, which rejects a
malformed one with the offending fields named, for the validationError of 6.6.4.1.
"""

from enum import StrEnum

from pydantic import Field

from agv_nodes.vda5050.common import (
    Action,
    Angle,
    Header,
    NodePosition,
    Omittable,
    Trajectory,
    Uint32,
    Vda5050Model,
)


class OrientationType(StrEnum):
    """How an edge's orientation is meant (6.6.6); 'TANGENTIAL' when not given."""

    # The order schema has no enum for this field, only a description; 6.6.6 defines the enum.
    GLOBAL = 'GLOBAL'
    TANGENTIAL = 'TANGENTIAL'


class CorridorRefPoint(StrEnum):
    """Which part of the truck a corridor bounds (6.6.5); 'KINEMATICCENTER' when not given."""

    KINEMATICCENTER = 'KINEMATICCENTER'
    CONTOUR = 'CONTOUR'


class Corridor(Vda5050Model):
    """Boundaries left and right of an edge's trajectory the truck may deviate within (6.6.5)."""

    left_width: float = Field(ge=0)
    right_width: float = Field(ge=0)
    corridor_ref_point: Omittable[CorridorRefPoint] = None


class Node(Vda5050Model):
    """A node of an order (6.6.6)."""

    node_id: str
    sequence_id: Uint32
    node_description: Omittable[str] = None
    released: bool
    node_position: Omittable[NodePosition] = None
    actions: list[Action]  # empty when the node has none


class Edge(Vda5050Model):
    """A directed edge of an order between two of its nodes (6.6.6)."""

    edge_id: str
    sequence_id: Uint32
    edge_description: Omittable[str] = None
    released: bool
    start_node_id: str
    end_node_id: str
    max_speed: Omittable[float] = None
    max_height: Omittable[float] = None
    min_height: Omittable[float] = None
    orientation: Omittable[Angle] = None
    orientation_type: Omittable[OrientationType] = None
    direction: Omittable[str] = None
    rotation_allowed: Omittable[bool] = None
    max_rotation_speed: Omittable[float] = None
    trajectory: Omittable[Trajectory] = None
    length: Omittable[float] = None
    corridor: Omittable[Corridor] = None
    actions: list[Action]  # empty when the edge has none


class Order(Header):
    """A new order or an order update (6.6.6)."""

    order_id: str
    order_update_id: Uint32
    zone_set_id: Omittable[str] = None
    nodes: list[Node]
    edges: list[Edge]  # empty for an order of one node


class InstantActions(Header):
    """Actions to start at once, outside the order (6.9)."""

    actions: list[Action]
