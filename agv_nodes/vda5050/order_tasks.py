"""An order against the track graph: its checks, its stop points and their task texts.

The half of the order flow (order_flow.py, whose docstring states the mapping) that looks only
at one order message: whether its nodes and edges are the track graph's, whether its sequence
ids and release follow 6.6.1 and 6.6.2, whether its actions are ones the truck can do (6.6.4.2),
and which released nodes the truck stops at, with the task that takes it there and the way the
task language drives to it. Errors come back as the state's Error objects (6.10.6, 7.1).
The small types and names both halves share live here too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from agv_nodes.communications.report_line import STATE_WORDS
from agv_nodes.fleet.track_graph import TrackGraph, TrackNode
from agv_nodes.records import codec
from agv_nodes.vda5050.common import Action
from agv_nodes.vda5050.order import Edge, Node, Order
from agv_nodes.vda5050.state import (
    ActionState,
    ActionStatus,
    EdgeState,
    Error,
    ErrorLevel,
    ErrorReference,
    NodeState,
)
from agv_nodes.vda5050.task_way import task_way, way_tasks

ORDER_ERROR = 'orderError'
NO_ROUTE_ERROR = 'noRouteError'
ORDER_UPDATE_ERROR = 'orderUpdateError'
NO_ORDER_TO_CANCEL = 'noOrderToCancel'
TASK_FAILED = 'taskFailed'
BRIDGE_ERROR = 'bridgeError'
INSTANT_ACTION_ERROR = 'instantActionError'  # 2.1 names no type for an unknown instant action

ABORT = 'abort'
DONE = (ActionStatus.FINISHED, ActionStatus.FAILED)
# the words of the truck's report lines (communications' own) for a task's states
TASK_STATES = tuple(STATE_WORDS[s] for s in ('running', 'step_done', 'completed', 'failed',
                                             'rejected'))
# The task language's pause commands (startPause, stopPause): not tasks, never queued.
PAUSE, RESUME = 'pause', 'resume'
CANNOT_PAUSE = 'this truck cannot pause'

# The node actions the task language can carry out, and the task verb of each.
TASK_VERBS = {'pick': 'load', 'drop': 'unload', 'wait': 'wait'}
WAIT_PARAMETER = 'duration'  # seconds, a whole number the wait task's byte can hold
WAIT_MAX = codec()['comms_status'].field('dwell').hi  # what comms_status can carry
ACTIONS_PER_NODE = 1  # one stop carries one task (the factsheet's maxArrayLens node.actions)

# Records one orderError: its description and the references beyond the order's own.
Fail = Callable[..., None]


def make_error(error_type: str, description: str, references: list[tuple[str, str]],
               level: ErrorLevel = ErrorLevel.WARNING) -> Error:
    """Return an Error with its references as (referenceKey, referenceValue) pairs."""
    return Error(error_type=error_type, error_description=description, error_level=level,
                 error_references=[ErrorReference(reference_key=k, reference_value=str(v))
                                   for k, v in references])


def order_references(order: Order) -> list[tuple[str, str]]:
    """Return what identifies an order message in an error (7.1)."""
    return [('topic', 'order'), ('headerId', str(order.header_id)),
            ('orderId', order.order_id), ('orderUpdateId', str(order.order_update_id))]


def base_count(order: Order) -> int:
    """Return how many of the order's nodes are released (the base's nodes, 6.6.1)."""
    return sum(1 for node in order.nodes if node.released)


def _wait_seconds(action: Action) -> int | None:
    """Return the wait action's duration in whole seconds 0-255, or None when it has none."""
    value = next((p.value for p in action.action_parameters or ()
                  if p.key == WAIT_PARAMETER), None)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    if isinstance(value, float) and not value.is_integer():
        return None
    return int(value) if 0 <= value <= WAIT_MAX else None


def _marker(node: TrackNode) -> str:
    """Return the task language's word for stop marker `node`: first or second."""
    return 'second' if node.conveyor == 1 else 'first'


def task_text(node: TrackNode, action: Action | None) -> str:
    """Return the task that drives to stop marker `node` and carries out `action` there."""
    marker = _marker(node)
    if action is None:
        return f'stop at {node.location} {marker}'
    verb = TASK_VERBS[action.action_type]
    if verb == 'wait':
        return f'wait at {node.location} for {_wait_seconds(action)} s {marker}'
    return f'{verb} at {node.location} {marker}'


def position_text(node: TrackNode) -> str:
    """Return the task that tells the truck it stands at stop marker `node` (initPosition)."""
    return f'at {node.location} {_marker(node)}'


def init_position_node(action: Action) -> str:
    """Return initPosition's parameter lastNodeId ('' without one)."""
    return next((str(p.value) for p in action.action_parameters or []
                 if p.key == 'lastNodeId'), '')


def position_refused(task: PositionTask, task_id: int, state: str, cause: str) -> Error:
    """Return the instantActionError of an initPosition whose `at` task the truck refused."""
    words = f'{state}: {cause}' if cause else state
    return make_error(INSTANT_ACTION_ERROR, f'initPosition: the truck refused task {task_id} '
                      f'(at {task.node_id}): {words}; it does not know where it stands',
                      [('actionId', task.action_id), ('actionType', 'initPosition'),
                       ('taskId', str(task_id))])


def task_failed_error(stop: StopPoint, task_id: int, words: str, order_id: str,
                      order_update_id: int) -> Error:
    """Return the taskFailed error of the task to `stop` (`words`: its state and cause)."""
    refs = [('orderId', order_id), ('orderUpdateId', str(order_update_id)),
            ('nodeId', stop.node_id), ('sequenceId', str(stop.sequence_id)),
            ('taskId', str(task_id))]
    if stop.action:
        refs.append(('actionId', stop.action.action_id))
    return make_error(TASK_FAILED, f'task {task_id} {stop.text!r} to {stop.node_id}: {words}; '
                      'the truck stopped and the order with it: a new order is needed', refs)


def check_order(order: Order, graph: TrackGraph, *, update: bool) -> list[Error]:
    """Return the orderErrors of an order or update (empty: it is one the truck can carry out).

    Checked: 6.6.1's shape (one edge fewer than nodes, released nodes and edges a prefix that
    ends with a node), 6.6.2's sequence ids (nodes even, edges odd, consecutive), nodes and
    edges of the track graph joining in the order's sequence, and actions the truck can do
    (6.6.4.2): one pick, drop or wait per stop marker node. An update's first node is the
    stitching node, whose actions are the first order's (6.6.2), so its actions are not looked
    at; a new order's first node is where the truck already is, where no task can act.
    """
    refs = order_references(order)
    errors: list[Error] = []

    def fail(description: str, *more: tuple[str, str]) -> None:
        errors.append(make_error(ORDER_ERROR, description, [*refs, *more]))

    nodes, edges = order.nodes, order.edges
    if not nodes:
        fail('an order needs at least one node (6.6.1)')
        return errors
    if len(edges) != len(nodes) - 1:
        fail(f'{len(nodes)} nodes need {len(nodes) - 1} edges, not {len(edges)} (6.6.1)')
        return errors
    first = nodes[0].sequence_id
    if first % 2:
        fail(f'node {nodes[0].node_id}: a node sequenceId is even (6.6.2), not {first}',
             ('nodeId', nodes[0].node_id), ('sequenceId', str(first)))
    for i, node in enumerate(nodes):
        if node.sequence_id != first + 2 * i:
            fail(f'node {node.node_id}: sequenceId {node.sequence_id}, expected {first + 2 * i}'
                 ' (nodes and edges alternate with consecutive sequenceIds, 6.6.2)',
                 ('nodeId', node.node_id), ('sequenceId', str(node.sequence_id)))
    for i, edge in enumerate(edges):
        if edge.sequence_id != first + 2 * i + 1:
            fail(f'edge {edge.edge_id}: sequenceId {edge.sequence_id}, expected '
                 f'{first + 2 * i + 1} (6.6.2)',
                 ('edgeId', edge.edge_id), ('sequenceId', str(edge.sequence_id)))
    _check_release(order, fail)
    _check_graph(order, graph, fail)
    _check_actions(order, graph, update, fail)
    return errors


def _check_release(order: Order, fail: Fail) -> None:
    """6.6.1: the base is a released prefix of the sequence that ends with a node."""
    items: list[tuple[str, str, int, bool]] = []
    for i, node in enumerate(order.nodes):
        items.append(('nodeId', node.node_id, node.sequence_id, node.released))
        if i < len(order.edges):
            edge = order.edges[i]
            items.append(('edgeId', edge.edge_id, edge.sequence_id, edge.released))
    if not items[0][3]:
        fail(f'the first node {items[0][1]} is not released: the base starts with it (6.6.1)',
             ('nodeId', items[0][1]), ('sequenceId', str(items[0][2])))
    for (_, _, _, before), (key, name, seq, released) in zip(items, items[1:], strict=False):
        if released and not before:
            fail(f'{key[:4]} {name} is released after an unreleased one (6.6.1)',
                 (key, name), ('sequenceId', str(seq)))
    base = [item for item in items if item[3]]
    if base and base[-1][0] == 'edgeId':
        key, name, seq, _ = base[-1]
        fail(f'the base ends with edge {name}: an edge is released only with its end node '
             '(6.6.1)', (key, name), ('sequenceId', str(seq)))


def _check_graph(order: Order, graph: TrackGraph, fail: Fail) -> None:
    """Check that the nodes and edges are the track graph's, each joining its neighbours."""
    for node in order.nodes:
        if node.node_id not in graph.nodes:
            fail(f'node {node.node_id} is not a node of the track graph',
                 ('nodeId', node.node_id), ('sequenceId', str(node.sequence_id)))
    for i, edge in enumerate(order.edges):
        a, b = order.nodes[i].node_id, order.nodes[i + 1].node_id
        refs = (('edgeId', edge.edge_id), ('sequenceId', str(edge.sequence_id)))
        if (edge.start_node_id, edge.end_node_id) != (a, b):
            fail(f'edge {edge.edge_id} runs {edge.start_node_id} -> {edge.end_node_id}, but '
                 f'its place in the order is between {a} and {b}', *refs,
                 ('startNodeId', edge.start_node_id), ('endNodeId', edge.end_node_id))
            continue
        known = graph.edges.get(edge.edge_id)
        if known is None:
            fail(f'edge {edge.edge_id} is not an edge of the track graph'
                 + (f' (the one from {a} to {b} is {graph.edge(a, b).id})'
                    if graph.edge(a, b) else ''), *refs)
        elif (known.start, known.end) != (a, b):
            fail(f'edge {edge.edge_id} of the track graph runs {known.start} -> {known.end}, '
                 f'not {a} -> {b}', *refs)
        elif edge.direction is not None and graph.direction(known) not in (None,
                                                                           edge.direction):
            fail(f'edge {edge.edge_id}: direction {edge.direction!r}, but at junction {a} '
                 f'that edge goes {graph.direction(known)!r}', *refs,
                 ('direction', edge.direction))


def _check_actions(order: Order, graph: TrackGraph, update: bool, fail: Fail) -> None:
    """6.6.4.2: only actions the truck can do, on stop markers, one per node."""
    seen: set[str] = set()
    for edge in order.edges:
        for action in edge.actions:
            fail(f'edge {edge.edge_id}: action {action.action_type}: this truck has no edge '
                 'actions (it acts only where it stands, at a stop marker)',
                 ('edgeId', edge.edge_id), ('actionId', action.action_id),
                 ('actionType', action.action_type))
    for i, node in enumerate(order.nodes):
        if i == 0 and update:
            continue  # the stitching node keeps the first order's actions (6.6.2)
        refs = (('nodeId', node.node_id), ('sequenceId', str(node.sequence_id)))
        if i == 0 and node.actions:
            fail(f'node {node.node_id}: actions on the start node: the truck is already there '
                 'and its tasks act only where they stop', *refs,
                 *(('actionId', a.action_id) for a in node.actions))
            continue
        if len(node.actions) > ACTIONS_PER_NODE:
            fail(f'node {node.node_id}: {len(node.actions)} actions; one stop carries one '
                 'task, so one action per node', *refs,
                 *(('actionId', a.action_id) for a in node.actions))
        track_node = graph.nodes.get(node.node_id)
        for action in node.actions:
            action_refs = (*refs, ('actionId', action.action_id),
                           ('actionType', action.action_type))
            if action.action_id in seen:
                fail(f'actionId {action.action_id} appears twice in the order', *action_refs)
            seen.add(action.action_id)
            if action.action_type not in TASK_VERBS:
                fail(f'node {node.node_id}: action type {action.action_type!r} is not one this '
                     f'truck can do (it can: {", ".join(TASK_VERBS)})', *action_refs)
            elif track_node is not None and not track_node.stoppable:
                fail(f'node {node.node_id} is a location marker the truck passes: an action '
                     'needs a stop marker', *action_refs)
            elif action.action_type == 'wait' and _wait_seconds(action) is None:
                fail(f'node {node.node_id}: wait needs actionParameter {WAIT_PARAMETER!r}, '
                     f'whole seconds 0-{WAIT_MAX}', *action_refs,
                     ('actionParameter', WAIT_PARAMETER))


@dataclass(eq=False)
class StopPoint:
    """A released node a task of the order ends at, and that task.

    Mostly a stop; on a floor of repeated identities also a location marker a `pass N` task
    drives past, and at a junction the location marker a `srm at N angle A` task leaves the
    wire at (way_tasks).
    """

    node_id: str
    sequence_id: int
    text: str
    action: Action | None  # the node's action; None for a plain stop at the base's end, a pass
    task_id: int | None = None  # the truck's id, once it has queued the task
    reached: bool = False
    done: bool = False


def stop_points(order: Order, graph: TrackGraph, anchor_passed: bool
                ) -> tuple[list[StopPoint], list[Error]]:
    """Return the stop points of the order's base after its first node, or noRouteErrors.

    A stop point is a released node with an action or the last released node; its way from the
    previous one (from the first node for the first) must be the way its tasks drive
    (way_tasks), else the order is a noRouteError naming the node. Where that takes more than
    one task, the markers passed by `pass N` tasks and the junctions left by `srm at N` are
    points too (the truck does not stop).
    `anchor_passed` is False only when the first node is one the truck has not passed yet.
    The order has passed check_order.
    """
    released = [node for node in order.nodes if node.released]
    points: list[StopPoint] = []
    errors: list[Error] = []
    anchor = 0
    for i, node in enumerate(released[1:], start=1):
        last = i == len(released) - 1
        if not node.actions and not last:
            continue
        track_node = graph.nodes[node.node_id]
        refs = [*order_references(order), ('nodeId', node.node_id),
                ('sequenceId', str(node.sequence_id))]
        if not track_node.stoppable:
            errors.append(make_error(
                ORDER_ERROR, f'the base ends on {node.node_id}, a location marker the truck '
                'passes and cannot stop at: the base must end on a stop marker', refs))
            break
        ordered = [n.node_id for n in released[anchor:i + 1]]
        passed = anchor_passed or anchor > 0
        tasks = way_tasks(graph, ordered, passed)
        if tasks is None:
            way = task_way(graph, ordered[0], passed, node.node_id)
            drives = ' -> '.join(way) if way else 'no way'
            errors.append(make_error(
                NO_ROUTE_ERROR, f'node {node.node_id}: the order goes {" -> ".join(ordered)}, '
                f'but the tasks to it drive {drives}: a task reaches a stop marker by the '
                "route map, past the next marker of its location, or by a junction's SRM",
                refs))
            break
        for k, text in tasks:  # markers passed, junctions left by SRM: a task each
            on = released[anchor + k]
            points.append(StopPoint(on.node_id, on.sequence_id, text, None))
        points.append(StopPoint(node.node_id, node.sequence_id,
                                task_text(track_node, _first(node)), _first(node)))
        anchor = i
    return points, errors


def _first(node: Node) -> Action | None:
    return node.actions[0] if node.actions else None


@dataclass
class Outcome:
    """What the bridge does after a message or a report: send tasks, publish state/factsheet."""

    verdict: str  # 'accepted' | 'updated' | 'ignored' | 'rejected' | 'instant' | 'progress'
    tasks: list[str] = field(default_factory=list)  # task texts to send, in this order
    publish_state: bool = False
    publish_factsheet: bool = False
    errors: list[Error] = field(default_factory=list)  # the errors this raised

    def __bool__(self) -> bool:
        """Return publish_state: a task report's outcome reads as 'the state changed'."""
        return self.publish_state


@dataclass(eq=False)
class AbortTask:
    """An abort the flow sent: for a cancelOrder (its actionId) or after a failed task."""

    action_id: str | None
    done: bool = False


@dataclass(eq=False)
class PositionTask:
    """The `at` task the flow sent for an initPosition (its actionId): where the truck stands."""

    action_id: str
    node_id: str
    before: tuple[str, int]  # lastNodeId and lastNodeSequenceId before the initPosition
    done: bool = False


Sent = StopPoint | AbortTask | PositionTask  # what a task the flow sent is for


def action_state(action: Action, status: ActionStatus) -> ActionState:
    """Return the actionState of an action (6.10.6)."""
    return ActionState(action_id=action.action_id, action_type=action.action_type,
                       action_description=action.action_description, action_status=status)


def node_state(node: Node) -> NodeState:
    """Return the nodeState of an order node still to traverse (6.10.6)."""
    return NodeState(node_id=node.node_id, sequence_id=node.sequence_id,
                     node_description=node.node_description, released=node.released,
                     node_position=node.node_position)


def edge_state(edge: Edge) -> EdgeState:
    """Return the edgeState of an order edge still to traverse (6.10.6)."""
    return EdgeState(edge_id=edge.edge_id, sequence_id=edge.sequence_id,
                     edge_description=edge.edge_description, released=edge.released,
                     trajectory=edge.trajectory)
