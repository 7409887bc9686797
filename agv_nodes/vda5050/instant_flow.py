"""VDA 5050 2.1 instant actions (6.9) for the 1983 wire-guided truck, the order flow's part.

cancelOrder sends `abort` and is RUNNING until the abort task has ended (6.6.3); initPosition
at a stop marker sets lastNodeId and tells the truck by the task `at N M` (docs/tasks.md);
startPause sends `pause` and stopPause `resume` (commands of the task language, not queued
tasks), each RUNNING until the truck's executive says it is at rest in its pause, or driving
again (truck_paused: its report lines, not the request, move them; 6.8.2's table); stateRequest
and factsheetRequest ask the bridge to publish; any other type FAILS with an error. Every one is
echoed in actionStates. A mixin of agv_nodes.vda5050.order_flow.OrderFlow, whose state it
shares.

The pause stops driving only: a pick, drop or wait in hand goes on (6.8.2: "Actions can
continue"), so no actionState is ever PAUSED, the status 6.11 names and the 2.1.0 state
schema's enum lacks (agv_nodes.vda5050.state keeps it, as the text does).
"""

from __future__ import annotations

from collections import deque
from typing import Any

from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.vda5050.order import InstantActions
from agv_nodes.vda5050.order_tasks import (
    ABORT,
    CANNOT_PAUSE,
    INSTANT_ACTION_ERROR,
    NO_ORDER_TO_CANCEL,
    PAUSE,
    RESUME,
    AbortTask,
    Outcome,
    PositionTask,
    Sent,
    action_state,
    init_position_node,
    make_error,
    position_refused,
    position_text,
)
from agv_nodes.vda5050.state import ActionState, ActionStatus, Error


class InstantActionFlow:
    """Instant actions and the end of their tasks (see the module docstring)."""

    # Shared with OrderFlow, which sets them up.
    graph: TrackGraph
    order_id: str
    last_node_id: str
    last_node_sequence_id: int
    errors: list[Error]
    pause: str
    _pause_actions: dict[str, str]
    _actions: dict[str, ActionState]
    _instant: set[str]
    _sent: deque[tuple[str, Sent]]

    def _order_active(self) -> bool:
        raise NotImplementedError

    def _stop_order(self, why: str) -> bool:
        raise NotImplementedError

    def on_instant_actions(self, msg: InstantActions) -> Outcome:
        """Carry out instant actions; one already known by its actionId is ignored."""
        out = Outcome('instant')
        refs = [('topic', 'instantActions'), ('headerId', str(msg.header_id))]
        for action in msg.actions:
            if action.action_id in self._actions:
                continue
            out.publish_state = True
            action_refs = [*refs, ('actionId', action.action_id),
                           ('actionType', action.action_type)]
            kind = action.action_type
            state = action_state(action, ActionStatus.FINISHED)
            if kind == 'cancelOrder':
                if self._order_active():
                    state.action_status = ActionStatus.RUNNING  # until the abort has ended
                    self._stop_order(f'cancelled by cancelOrder {action.action_id}')
                    self._sent.append((ABORT, AbortTask(action.action_id)))
                    out.tasks.append(ABORT)
                else:  # 6.6.3.2
                    state.action_status = ActionStatus.FAILED
                    out.errors.append(make_error(
                        NO_ORDER_TO_CANCEL, 'cancelOrder: the truck has no order to cancel '
                        '(none, ended, or cancelled already; 6.6.3.2)', action_refs))
            elif kind == 'stateRequest':
                pass  # FINISHED: the state the bridge publishes now is the answer
            elif kind == 'factsheetRequest':
                out.publish_factsheet = True
            elif kind == 'initPosition':
                self._init_position(action, state, action_refs, out)
            elif kind in ('startPause', 'stopPause'):
                self._pause_action(action.action_id, kind, state, out)
            else:
                state.action_status = ActionStatus.FAILED
                out.errors.append(make_error(
                    INSTANT_ACTION_ERROR, f'instant action type {kind!r} is not one this truck '
                    'can do (it can: cancelOrder, initPosition, startPause, stopPause, '
                    'stateRequest, factsheetRequest)',
                    action_refs))
            self._actions[action.action_id] = state
            self._instant.add(action.action_id)
        self.errors.extend(e for e in out.errors if e not in self.errors)
        return out

    def _pause_action(self, action_id: str, kind: str, state: ActionState,
                      out: Outcome) -> None:
        """Take startPause or stopPause (6.8.2): send `pause` or `resume` to the truck.

        FINISHED at once when the truck already is where it asks (at rest in its pause, or not
        paused), else RUNNING until it says so. One of the other kind still RUNNING is
        overtaken: FAILED, as it will not come to pass.
        """
        for other, other_kind in list(self._pause_actions.items()):
            if other_kind != kind:
                self._end_pause_action(other, ActionStatus.FAILED,
                                       f'overtaken by {kind} {action_id}')
        out.tasks.append(PAUSE if kind == 'startPause' else RESUME)
        if self.pause == 'unable':
            state.action_status, state.result_description = ActionStatus.FAILED, CANNOT_PAUSE
        elif self.pause == ('paused' if kind == 'startPause' else 'none'):
            state.action_status = ActionStatus.FINISHED
        else:
            state.action_status = ActionStatus.RUNNING
            self._pause_actions[action_id] = kind

    def truck_paused(self, pause: str) -> bool:
        """Take the executive's word on the pause; return True when the state changed.

        `pause`: comms_command's none, stopping, paused or unable. At rest in the pause ends a
        startPause (FINISHED, paused true), driving again a stopPause; unable fails either.
        """
        changed = pause != self.pause
        self.pause = pause
        for action_id, kind in list(self._pause_actions.items()):
            if pause == 'unable':
                self._end_pause_action(action_id, ActionStatus.FAILED, CANNOT_PAUSE)
            elif pause == ('paused' if kind == 'startPause' else 'none'):
                self._end_pause_action(action_id, ActionStatus.FINISHED)
            else:
                continue
            changed = True
        return changed

    def _end_pause_action(self, action_id: str, status: ActionStatus, why: str = '') -> None:
        del self._pause_actions[action_id]
        state = self._actions.get(action_id)
        if state is not None:
            state.action_status, state.result_description = status, why or None

    def _init_position(self, action: Any, state: ActionState, refs: list[tuple[str, str]],
                       out: Outcome) -> None:
        """Take initPosition (6.8.2): the master says at which node the truck stands.

        The truck knows where it is only by the markers it passes: a truck set down at a stop
        marker (a fleet's second truck, or one moved by hand) learns it this way. Only a stop
        marker, where a truck can stand, and not while an order runs. The bridge takes it at
        once (lastNodeId; FINISHED) and tells the truck by the task `at N M`, so that it leaves
        as from a stop of its own (from W1.1 or W3.1 of demo_1983 by the location's SRM); a
        refusal (moving, a task running) makes it FAILED after all (_instant_ended).
        """
        node, why = init_position_node(action), ''
        if self._order_active():
            why = f'order {self.order_id} is active: the truck is where it drives'
        elif node not in self.graph.nodes or not self.graph.nodes[node].stoppable:
            why = f'lastNodeId {node!r} is no stop marker of the track graph'
        if why:
            state.action_status = ActionStatus.FAILED
            state.result_description = why
            out.errors.append(make_error(INSTANT_ACTION_ERROR, f'initPosition: {why}', refs))
            return
        before = (self.last_node_id, self.last_node_sequence_id)
        self.last_node_id, self.last_node_sequence_id = node, 0
        text = position_text(self.graph.nodes[node])
        self._sent.append((text, PositionTask(action.action_id, node, before)))
        out.tasks.append(text)

    def _instant_ended(self, task: AbortTask | PositionTask, task_id: int, state: str,
                       cause: str) -> bool:
        """Take the end of an instant action's task; return True when the state changed.

        An abort ends its cancelOrder (6.6.3: FINISHED once the truck stands still); an `at`
        task the truck refused fails its initPosition and takes lastNodeId back.
        """
        action = self._actions.get(task.action_id or '')
        if isinstance(task, AbortTask):
            if action is not None:
                action.action_status = ActionStatus.FINISHED if state != 'rejected' \
                    else ActionStatus.FAILED
            return action is not None
        if state == 'completed':
            return False  # the truck knows now what the bridge took at once
        error = position_refused(task, task_id, state, cause)
        if action is not None:
            action.action_status = ActionStatus.FAILED
            action.result_description = error.error_description
        if self.last_node_id == task.node_id and not self._order_active():
            self.last_node_id, self.last_node_sequence_id = task.before
        self.errors.append(error)
        return True
