"""VDA 5050 2.1 order handling for the 1983 wire-guided truck: orders in, task texts out.

The per-truck bridge lets a master control (e.g. openTCS) drive the truck, which knows no
orders, only tasks of the task language (docs/tasks.md). This is the bridge's logic without
ROS, MQTT or a clock: it takes parsed (schema-valid) Order and InstantActions messages and the
truck's task reports, and returns the task texts to send and every State field but the header.

The mapping:

- Nodes are track graph nodes (agv_nodes.fleet.track_graph), edges its edges, by id; each
  edge joins the nodes either side of it in the order. Sequence ids alternate node (even),
  edge (odd), consecutively (6.6.2); the released nodes and edges are a prefix that ends with a
  node (6.6.1): the base, the rest the horizon.
- The first node of a new order is where the truck is: its lastNodeId, or the layout's first
  node (TrackGraph.start) before it has passed any. The truck stops at every released node
  with an action and at the base's last node (the decision point); one task each, in order:
  `pick` -> `load at N M`, `drop` -> `unload at N M`, `wait` (parameter `duration`, whole
  seconds 0-255) -> `wait at N for S s M`, none -> `stop at N M`, where N is the node's
  location and M `first` or `second` its stop marker. Only stop markers can carry an action or
  end the base; at most one action a node; none on edges or on the start node.
- A task drives along the route map to the next marker of its location and on to its stop
  marker (agv_nodes.vda5050.task_way); the order's way to each stop point must be the way of
  its tasks, or the order is a noRouteError naming the stop point (W2.1 -> W2.2 directly,
  say: the task to W2.2 passes L2 first, a lap on). Where a floor repeats identities (house
  numbers), each marker of the stop's identity on the way before its own is driven past by a
  task `pass N` first; the master sees only its nodes pass.
- Rejections (6.6.4, 6.10.6, references per 7.1): orderError (shape, ids, actions),
  noRouteError (start out of reach, stop point the task language cannot reach as ordered),
  orderUpdateError (lower orderUpdateId, a continuation not starting at the decision point,
  a new orderId while an order is active), noOrderToCancel. A rejected order changes nothing
  else; the errors stay until an order or update is accepted (6.6.4.1-6.6.4.3).
- Progress comes from the truck's report lines, which the bridge parses: task_queued pairs
  the truck's task id with the oldest text sent and not yet paired (the `task N abort: ...`
  line included, as text 'abort'); task_state moves the states. A location marker passed
  clears the nodes up to it; the goto step done (or a stop task completed) reaches the stop
  point (6.10.2): its action RUNNING, FINISHED when the task completes. A failed or rejected
  task fails the rest of the order and clears its nodes; an `abort` then drops the tasks
  already queued, which the truck would otherwise go on with.
- Instant actions (6.9): agv_nodes.vda5050.instant_flow.

The truck stops at the decision point even when an update extends the base in time: its
stop task is on the truck by then, and a task cannot be taken back.
"""

from __future__ import annotations

from collections import deque
from typing import Any

from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.vda5050.instant_flow import InstantActionFlow
from agv_nodes.vda5050.order import Edge, Node, Order
from agv_nodes.vda5050.order_tasks import (
    ABORT,
    BRIDGE_ERROR,
    DONE,
    NO_ROUTE_ERROR,
    ORDER_ERROR,
    ORDER_UPDATE_ERROR,
    TASK_STATES,
    AbortTask,
    Outcome,
    Sent,
    StopPoint,
    action_state,
    check_order,
    edge_state,
    make_error,
    node_state,
    order_references,
    stop_points,
    task_failed_error,
)
from agv_nodes.vda5050.state import ActionState, ActionStatus, Error, ErrorLevel


class OrderFlow(InstantActionFlow):
    """The order, its progress and the action states of one truck (see the module docstring)."""

    def __init__(self, graph: TrackGraph) -> None:
        self.graph = graph
        self.order_id = ''
        self.order_update_id = 0
        self.last_node_id = ''
        self.last_node_sequence_id = 0
        self.driving = False
        self.errors: list[Error] = []
        self._had_order = False
        self._nodes: list[Node] = []  # still to traverse: the nodeStates
        self._edges: list[Edge] = []
        self._actions: dict[str, ActionState] = {}  # order and instant actions, as received
        self._instant: set[str] = set()  # which of them are instant actions
        self._stops: list[StopPoint] = []  # the order's stop points not yet done
        self._sent: deque[tuple[str, Sent]] = deque()  # sent, not yet queued
        self._tasks: dict[int, Sent] = {}  # by the truck's task id
        self._base_end: tuple[str, int] | None = None  # the decision point (6.6.2)
        self._base_end_passed = True  # False: it is the start node, not reached yet
        self.pause = 'none'  # the truck's pause, as its executive last said (comms_command)
        self._pause_actions: dict[str, str] = {}  # startPause/stopPause actionId -> type

    # -- orders (6.6) ----------------------------------------------------------------------
    def on_order(self, order: Order) -> Outcome:
        """Accept, stitch, ignore or reject an order as the flow of 6.6.2 (figure 8) says."""
        if self._had_order and order.order_id == self.order_id:
            return self._on_update(order)
        errors = check_order(order, self.graph, update=False)
        if errors:
            return self._reject(errors)
        refs = order_references(order)
        if self._active():  # figure 8 (3): a new order waits for the current one to end
            return self._reject([make_error(
                ORDER_UPDATE_ERROR, f'order {order.order_id}: order {self.order_id} is still '
                'active (nodes left or actions not ended): a new orderId is accepted once it '
                'has ended or been cancelled (6.6.2, figure 8)',
                [*refs, ('currentOrderId', self.order_id)])])
        start = self.last_node_id or self.graph.start
        first = order.nodes[0]
        if first.node_id != start:  # figure 8 (4)
            return self._reject([make_error(
                NO_ROUTE_ERROR, f'the order starts at {first.node_id}, but the truck is at '
                f'{start}: the first node must be trivially reachable (6.6.1)',
                [*refs, ('nodeId', first.node_id), ('sequenceId', str(first.sequence_id))])])
        passed = bool(self.last_node_id)
        points, errors = stop_points(order, self.graph, passed)
        if errors:
            return self._reject(errors)
        # 6.10.6: a new order removes the action states but those of running instant actions.
        self._actions = {k: a for k, a in self._actions.items()
                         if k in self._instant and a.action_status not in DONE}
        self._instant &= set(self._actions)
        self._had_order = True
        self.order_id, self.order_update_id = order.order_id, order.order_update_id
        self._edges, self._stops = list(order.edges), []
        if passed:  # 6.10.6: the truck stands at the first node
            self.last_node_sequence_id = first.sequence_id
            self._nodes = list(order.nodes[1:])
        else:  # the first card ahead: lastNodeId once the truck has read it
            self._nodes = list(order.nodes)
        self._base_end_passed = passed
        return self._take(order, points, 'accepted')

    def _on_update(self, order: Order) -> Outcome:
        refs = order_references(order)
        if order.order_update_id < self.order_update_id:
            return self._reject([make_error(
                ORDER_UPDATE_ERROR, f'orderUpdateId {order.order_update_id} is lower than '
                f'{self.order_update_id}, the one the truck has: a deprecated update (6.6.4.3)',
                refs)])
        if order.order_update_id == self.order_update_id:
            # 6.6.4.3: the same update twice is ignored; the master likely resent it for want
            # of a state, so one is published.
            return Outcome('ignored', publish_state=True)
        errors = check_order(order, self.graph, update=True)
        if errors:
            return self._reject(errors)
        first = order.nodes[0]
        stitch = (first.node_id, first.sequence_id)
        if self._active():  # figure 8 (7): continue at the decision point
            expected, what = self._base_end, 'the last node of the current base'
        else:  # figure 8 (8): continue from the last node the truck reached
            expected = (self.last_node_id, self.last_node_sequence_id)
            what = 'the last node the truck reached'
        if stitch != expected:
            have = f'{expected[0]} (sequenceId {expected[1]})' if expected else 'none'
            return self._reject([make_error(
                ORDER_UPDATE_ERROR, f'the update starts at {first.node_id} (sequenceId '
                f'{first.sequence_id}), not at {what}: {have} (6.6.2 stitching)',
                [*refs, ('nodeId', first.node_id), ('sequenceId', str(first.sequence_id))])])
        horizon = {a.action_id for n in self._nodes if not n.released for a in n.actions}
        kept = set(self._actions) - horizon
        twice = [(n, a) for n in order.nodes[1:] for a in n.actions if a.action_id in kept]
        if twice:
            return self._reject([make_error(
                ORDER_ERROR, f'node {n.node_id}: actionId {a.action_id} is one the truck has '
                'already', [*refs, ('nodeId', n.node_id), ('actionId', a.action_id)])
                for n, a in twice])
        passed = self._base_end_passed if stitch == self._base_end else True
        points, errors = stop_points(order, self.graph, passed)
        if errors:
            return self._reject(errors)
        # Figure 8: the horizon is replaced, the base grows from the stitching node.
        for action_id in horizon:
            self._actions.pop(action_id, None)
        self._nodes = [n for n in self._nodes if n.released] + list(order.nodes[1:])
        self._edges = [e for e in self._edges if e.released] + list(order.edges)
        self.order_update_id = order.order_update_id
        return self._take(order, points, 'updated')

    def _take(self, order: Order, points: list[StopPoint], verdict: str) -> Outcome:
        """Add the order's new actions and stop points, clear the errors, send the tasks."""
        for node in order.nodes[1:]:
            for action in node.actions:
                self._actions[action.action_id] = action_state(action, ActionStatus.WAITING)
        released = [n for n in order.nodes if n.released]
        if len(released) > 1:
            self._base_end = (released[-1].node_id, released[-1].sequence_id)
            self._base_end_passed = True  # a stop point: the truck will stand on it
        elif self._base_end is None or verdict == 'accepted':
            self._base_end = (released[0].node_id, released[0].sequence_id)
        self._stops.extend(points)
        self._sent.extend((p.text, p) for p in points)
        self.errors = []  # 6.6.4: reported until an order is accepted
        return Outcome(verdict, [p.text for p in points], publish_state=True)

    def _reject(self, errors: list[Error]) -> Outcome:
        self.errors.extend(e for e in errors if e not in self.errors)
        return Outcome('rejected', publish_state=True, errors=errors)

    def _active(self) -> bool:
        """Figure 8 (3): nodes left, or actions neither FINISHED nor FAILED."""
        return bool(self._nodes) or any(a.action_status not in DONE
                                        for a in self._actions.values())

    def _order_active(self) -> bool:
        return bool(self._nodes) or any(a.action_status not in DONE
                                        for k, a in self._actions.items()
                                        if k not in self._instant)

    def _stop_order(self, why: str) -> bool:
        """End the order where the truck is: its unfinished actions FAILED, no nodes left."""
        for action_id, state in self._actions.items():
            if action_id not in self._instant and state.action_status not in DONE:
                state.action_status = ActionStatus.FAILED
                state.result_description = state.result_description or why
        later = any(not s.done for s in self._stops)
        self._nodes, self._edges, self._stops = [], [], []
        self._base_end = None
        return later

    # -- the truck's reports ---------------------------------------------------------------
    def task_queued(self, task_id: int, text: str) -> bool:
        """Pair the truck's task id with the oldest task sent and not yet paired.

        Returns True when the state changed: a text other than the one expected is a
        bridgeError (FATAL: someone else is giving the truck tasks) and pairs nothing.
        """
        while self._sent and self._sent[0][0] == ABORT != text \
                and any(sent == text for sent, _ in self._sent):
            # The truck queues tasks as they were sent: an abort not queued before a later
            # task was never sent (a bridge that left out a task_state outcome's tasks).
            self._sent.popleft()
        expected = self._sent[0][0] if self._sent else None
        if text != expected:
            what = f'expected {expected!r}' if expected else 'sent none'
            error = make_error(BRIDGE_ERROR, f'the truck queued task {task_id} {text!r}; the '
                               f'bridge {what}', [('taskId', str(task_id))], ErrorLevel.FATAL)
            if error not in self.errors:
                self.errors.append(error)
            return True
        _, target = self._sent.popleft()
        if isinstance(target, StopPoint):
            target.task_id = task_id
        self._tasks[task_id] = target
        return False

    def task_state(self, task_id: int, state: str, step: int, cause: str,
                   last_marker: int | None) -> Outcome:
        """Move the order's states on a task report line.

        The outcome is truthy when the state changed (publish_state), as a bool would be; its
        tasks (an abort after a failed task) must be sent.
        """
        # A passage is a location other than the one the truck was last known past: the report
        # names the identity only, which a floor of house numbers repeats.
        here = self.graph.nodes.get(self.last_node_id)
        passage = last_marker is not None and (here is None or last_marker != here.location)
        target = self._tasks.get(task_id)
        out = Outcome('progress')
        if target is None or state not in TASK_STATES:
            return out
        driving = state == 'running' and step == 0 and isinstance(target, StopPoint)
        out.publish_state = driving != self.driving
        self.driving = driving
        if not isinstance(target, StopPoint):
            if state in ('completed', 'FAILED', 'rejected') and not target.done:
                target.done = True
                out.publish_state |= self._instant_ended(target, task_id, state, cause)
            return out
        if not any(s is target for s in self._stops):
            return out  # a task of an order that has ended
        if passage and last_marker is not None:
            out.publish_state |= self._passed_marker(last_marker, target)
        if (state == 'step done' and step == 0) or (state == 'running' and step > 0) \
                or state == 'completed':
            out.publish_state |= self._reach(target)
        if state == 'completed':
            target.done = True
            self._stops.remove(target)
            self._set_action(target, ActionStatus.FINISHED)
            out.publish_state = True
        elif state in ('FAILED', 'rejected'):
            out.tasks = self._fail(target, task_id, state, cause)
            out.publish_state = True
        return out

    def ahead(self) -> list[str]:
        """Return the order's nodes still to traverse, in order (the nodeStates' ids)."""
        return [n.node_id for n in self._nodes]

    def node_read(self, node_id: str) -> bool:
        """Take a card the truck read as `node_id`; return True when the state changed.

        A node of the order clears it and what comes before it (6.10.2: every node the truck
        passes is lastNodeId, stop markers too); without an order it is lastNodeId with
        lastNodeSequenceId 0 (6.10.6).
        """
        node = next((n for n in self._nodes if n.node_id == node_id), None)
        if node is not None:
            self._traversed(node.node_id, node.sequence_id)
            return True
        if node_id == self.last_node_id:
            return False
        self.last_node_id, self.last_node_sequence_id = node_id, 0
        return True

    def _passed_marker(self, marker: int, stop: StopPoint) -> bool:
        """Clear the nodes up to location `marker`, passed on the way to `stop`.

        The truck reports the identity only; the first node of it still ahead on the order's
        way is the marker it passed, where a floor repeats identities (house numbers).
        """
        for node in self._nodes:
            if node.sequence_id > stop.sequence_id:
                break
            track = self.graph.nodes.get(node.node_id)
            if track is not None and track.kind == 'location' and track.location == marker:
                self._traversed(node.node_id, node.sequence_id)
                return True
        return False

    def _reach(self, stop: StopPoint) -> bool:
        """Mark the stop point reached: its goto step is done, the truck stands on it (6.10.2)."""
        if stop.reached:
            return False
        stop.reached = True
        self._traversed(stop.node_id, stop.sequence_id)
        self._set_action(stop, ActionStatus.RUNNING)
        return True

    def _traversed(self, node_id: str, sequence_id: int) -> None:
        """6.10.2: the node and the edges up to it leave the states; it is the last node."""
        self._nodes = [n for n in self._nodes if n.sequence_id > sequence_id]
        self._edges = [e for e in self._edges if e.sequence_id > sequence_id]
        self.last_node_id, self.last_node_sequence_id = node_id, sequence_id
        self._base_end_passed = True

    def _set_action(self, stop: StopPoint, status: ActionStatus, why: str = '') -> None:
        state = self._actions.get(stop.action.action_id) if stop.action else None
        if state is not None and state.action_status not in DONE:
            state.action_status = status
            state.result_description = why or None

    def _fail(self, stop: StopPoint, task_id: int, state: str, cause: str) -> list[str]:
        """Stop the order at a failed or rejected task; return the tasks to send."""
        words = f'{state}: {cause}' if cause else state
        self.errors.append(task_failed_error(stop, task_id, words, self.order_id,
                                             self.order_update_id))
        self._set_action(stop, ActionStatus.FAILED, words)
        stop.done = True
        later = self._stop_order(f'the order stopped: task {task_id} {words}')
        self.driving = False
        if not later:
            return []
        # The truck would go on with the order's tasks still queued: an abort drops them.
        self._sent.append((ABORT, AbortTask(None)))
        return [ABORT]

    # -- the state (6.10) ------------------------------------------------------------------
    def state_fields(self) -> dict[str, Any]:
        """Return every State field this flow owns (all but header, position, battery...)."""
        horizon = any(not n.released for n in self._nodes)
        ahead = [s for s in self._stops if not s.reached]
        return {
            'order_id': self.order_id,
            'order_update_id': self.order_update_id,
            'last_node_id': self.last_node_id,
            'last_node_sequence_id': self.last_node_sequence_id,
            'node_states': [node_state(n) for n in self._nodes],
            'edge_states': [edge_state(e) for e in self._edges],
            # 6.10.6: paused once the truck is at rest in its pause (the executive's word)
            'driving': self.driving and self.pause != 'paused',
            'paused': self.pause == 'paused',
            # 6.10.3: on the way to the decision point with a horizon, ask for the next base.
            'new_base_request': horizon and len(ahead) <= 1,
            'action_states': [a.model_copy() for a in self._actions.values()],
            'errors': [e.model_copy(deep=True) for e in self.errors],
        }
