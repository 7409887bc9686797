"""The `at` task: the truck is told at which stop marker it stands (a modern addition).

A mixin of ExecutiveCore (agv_nodes.executive.core). The 1983 truck knows where it is only from
the markers it passes: Position reports the last location recognised (Baker 1983, fig 6.2,
bytes 2-3; location markers serve as landmarks, 4.4) and the executive decides at each one
whether the route map leaves the wire there (7.2, task 7). A truck lifted and set down at a
stop marker has passed none, so its executive does not know, for one, that leaving W1 or W3 of
demo_1983 must start that location's SRM (the station is a branch off the route map's way;
config/layouts/demo_1983.yaml): without it the truck follows the branch's wire off its end.

`at N [first|second]` (docs/tasks.md) hands it what passing the markers would have left it
with: location N as its last location marker (comms_command's `location`) and as the location
it stopped at, and the stop marker it stands at; the next task leaves from there as from a stop
made by a task (ExecutiveCore._enter: an SRM location's station starts the SRM on departure).
Nothing in the thesis sets a truck's position by a message; a fleet's central computer (Baker
1983, 6.7) that sets trucks down needs it, and the VDA 5050 bridge sends it for initPosition.

Only a truck at rest with no task running can be told: refused, with cause `task_running`
while a task runs, `moving` (traction) while the truck cruises on from its last task or
traction reports a speed above `rest_speed`; a refused `at` changes nothing else. It is no move
of the truck: it drives nothing and completes at once, taking a failed truck out of its fault
hold (as any new task would) to stand idle.
"""

from typing import Any

from agv_nodes.executive.itinerary import NO_TASK

MARKERS = ('first', 'second')  # comms_status marker values an `at` task can carry


class SetDown:
    """The `at` task (see the module docstring)."""

    def _set_down(self, fields: dict[str, Any], now: float) -> None:
        """Take an `at` task: where the truck stands, or a refusal naming why not."""
        where = f'L{fields["location"]}, stop marker {MARKERS.index(fields["marker"]) + 1}' \
            if fields['marker'] in MARKERS else f'L{fields["location"]}'
        refusal = self._set_down_refusal()
        if refusal is not None:
            cause, subsystem, why = refusal
            self.report = {'state': 'rejected', 'cause': cause, 'subsystem': subsystem}
            self._log(now, f'task {self.task_id}: at {where} refused: {why}')
            return
        if fields['marker'] not in MARKERS or fields['location'] > 31:
            self.report = {'state': 'rejected', 'cause': 'bad_task', 'subsystem': 'none'}
            self._log(now, f'task {self.task_id}: rejected (at {where}: not a stop marker)')
            return
        self.last_marker = self.stopped_at = fields['location']
        self.stop_marker = MARKERS.index(fields['marker'])
        self.mode, self.fault, self.steps, self.index = 'idle', None, [], 0
        self.demand, self.nav, self.slow = 0, (NO_TASK, 0), False
        self._srm_at = self._srm_pending = None
        self.distance = self.distance_since_landmark = self.positioning_distance = 0.0
        self.report = {'state': 'completed', 'cause': 'none', 'subsystem': 'none'}
        self._log(now, f'task {self.task_id}: at {where}: the last location marker and the '
                  'stop marker the truck stands at')

    def _set_down_refusal(self) -> tuple[str, str, str] | None:
        """Return (cause, subsystem, why) when the truck cannot be told now, else None."""
        if self.mode == 'running':
            return 'task_running', 'none', 'a task is running'
        if self.mode == 'cruising':
            return 'moving', 'traction', 'the truck cruises on from its last task'
        # No traction status yet: the truck has not been driven since it started.
        speed = abs((self.status.get('traction') or {}).get('speed', 0))
        if speed > self.p.rest_speed:
            return 'moving', 'traction', f'traction reports {speed} mm/s'
        return None
