"""A dispatcher's jobs and trucks, and the VDA 5050 messages it sends for them.

A job is one VDA 5050 order of a truck (agv_nodes.fleet.dispatcher): a transport's pick and
drop, or a drive to a parking or passing place; its nodes are the track graph's, node i with
sequenceId 2 i and the edge after it 2 i + 1, released up to the job's decision point.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise

from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.common import Action, BlockingType
from agv_nodes.vda5050.order import Edge, Node, Order
from agv_nodes.vda5050.order_tasks import TASK_FAILED
from agv_nodes.vda5050.state import ActionStatus, State

ORDER = 'order'
INSTANT_ACTIONS = 'instantActions'


@dataclass(frozen=True)
class TransportOrder:
    """Load at station `source` (e.g. 'W0') and take the load to station `destination`."""

    id: str
    source: str
    destination: str


@dataclass
class Job:
    """One VDA 5050 order of a truck: a transport, or a drive to a parking or passing place."""

    order_id: str
    transport: TransportOrder | None
    path: list[str]  # node i has sequenceId 2 i
    actions: dict[int, Action]  # by path index
    passed: bool  # path[0] is a node the truck has passed (False: the layout's start)
    base_end: int = 0  # the decision point's path index
    update_id: int = 0
    sent: bool = False
    over: bool = False
    failed: bool = False


@dataclass
class Truck:
    """What the dispatcher knows of one truck and the job it gave it."""

    name: str
    state: State | None = None
    job: Job | None = None
    pos: int = 0  # the path index of the job's node the truck last reached
    trail: list[str] = field(default_factory=list)  # the way it came, ending at its last node
    broken: bool = False
    offline: bool = False  # off the broker: no messages reach it (set_online)
    blocked_since: float | None = None  # since when it waits on trucks that cannot move
    headers: dict[str, int] = field(default_factory=lambda: {ORDER: 0, INSTANT_ACTIONS: 0})


def header(truck: Truck, topic: str, manufacturer: str) -> dict[str, object]:
    """Return the next header of `topic` for `truck` (headerIds count per topic, 6.2)."""
    header_id = truck.headers[topic]
    truck.headers[topic] += 1
    return {'header_id': header_id, 'timestamp': common.now(), 'version': VERSION,
            'manufacturer': manufacturer, 'serial_number': truck.name}


def order_message(graph: TrackGraph, truck: Truck, job: Job, first: int,
                  manufacturer: str) -> Order:
    """Return the job's order (first 0) or the update stitched on at path index `first`."""
    nodes = [Node(node_id=n, sequence_id=2 * i, released=i <= job.base_end,
                  actions=[job.actions[i]] if i in job.actions and i > first else [])
             for i, n in enumerate(job.path) if i >= first]
    edges = []
    for i, (a, b) in enumerate(pairwise(job.path)):
        if i >= first:
            edge = graph.edge(a, b)
            assert edge is not None, f'{a}-{b} is no edge: a planning error'
            edges.append(Edge(edge_id=edge.id, sequence_id=2 * i + 1,
                              released=i + 1 <= job.base_end, start_node_id=a,
                              end_node_id=b, direction=graph.direction(edge), actions=[]))
    return Order(**header(truck, ORDER, manufacturer), order_id=job.order_id,
                 order_update_id=job.update_id, nodes=nodes, edges=edges)


def hard_action(action_id: str, kind: str) -> Action:
    """Return a node action the truck does standing (pick, drop)."""
    return Action(action_id=action_id, action_type=kind, blocking_type=BlockingType.HARD)


def failure_words(state: State, action_ids: set[str]) -> str:
    """Return why a truck's order failed, in its own words (taskFailed, else a FAILED action)."""
    for error in state.errors:
        if error.error_type == TASK_FAILED:
            return error.error_description or TASK_FAILED
    for action in state.action_states:
        if action.action_id in action_ids and action.action_status == ActionStatus.FAILED:
            return action.result_description or f'action {action.action_id} FAILED'
    return 'no reason given'


def task_failed(state: State) -> bool:
    """Return True when the state reports a failed task of the truck."""
    return any(e.error_type == TASK_FAILED for e in state.errors)
