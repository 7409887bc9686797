"""Communications: tasks in from people and programs, reports out (Baker 3.3, 3.5.3, 7.2).

It parses the task text (syntax only; the task language: docs/tasks.md), queues the tasks, passes
the head of the queue to the executive as a comms_status record without interpreting it, and turns
the executive's comms_command records into readable reports. A bad task is rejected with the column
and the reason, and changes nothing.
"""

from typing import Any

from agv_nodes.communications.report_line import FINAL, abort_line, progress_line, queued_line
from agv_nodes.communications.task_language import Task, TaskError, parse_task
from agv_nodes.records.ports import DUPLICATE_WRITER
from agv_nodes.settings import settings_class
from agv_nodes.subsystem import SubsystemCore


@settings_class
class CommsParams:
    """The task queue and its relay to the executive (its parameters.yaml section)."""


class CommunicationsCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'communications', CommsParams, 'period'

    def __init__(self, params: CommsParams | None = None) -> None:
        super().__init__(params)
        self.queue: list[Task] = []
        self.results: list[tuple[int, str, str]] = []  # (task_id, final state, cause)
        self._next_id = 1
        self._last: tuple | None = None

    def on_task(self, text: str, now: float) -> dict | None:
        """Take a task from comms/task."""
        try:
            task = parse_task(text, self.p.locations)
        except TaskError as exc:
            self.notes.add(now, f'comms: {exc}')
            return None
        if task.op == 'status':  # a query: answered, never queued (demo.py's handshake)
            head = f'; head: task {self.queue[0].task_id} {self.queue[0].text!r}' \
                if self.queue else ''
            self.notes.add(now, f'comms: status: {len(self.queue)} in queue{head}')
            return None
        task.task_id = self._next_id
        self._next_id = self._next_id % 255 + 1
        if task.op == 'abort':
            self.notes.add(now, abort_line(task.task_id, len(self.queue)))
            self.queue = [task]
        else:
            self.queue.append(task)
            self.notes.add(now, queued_line(task.task_id, text, len(self.queue)))
        return self.tick(now)

    def on_reject(self, record: str, reason: str, now: float) -> dict | None:
        """Fail the head task when two live executives both write comms_command.

        Neither's word can be relayed (records.writer_check rejects both), and a report that
        says nothing would leave its sender waiting: the line names the duplicate instead.
        """
        if reason != DUPLICATE_WRITER or not self.queue:
            return None
        task = self.queue.pop(0)
        self.notes.add(now, progress_line(task.task_id, task.text, {
            'state': 'failed', 'step': 0, 'cause': DUPLICATE_WRITER, 'subsystem': 'executive',
            'location': 0xFF}), 'warn')
        self.results.append((task.task_id, 'failed', DUPLICATE_WRITER))
        return self.tick(now)

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """comms_command: the executive's word on a task."""
        # the location too: a line for each location marker passed tells a master control
        # (the VDA 5050 bridge) which node the truck has reached
        key = (fields['task_id'], fields['state'], fields['step'], fields['cause'],
               fields['location'])
        if key == self._last or not self.queue or fields['task_id'] != self.queue[0].task_id:
            return None
        self._last = key
        task = self.queue[0]
        line = progress_line(task.task_id, task.text, fields)
        self.notes.add(now, line)
        if fields['state'] in FINAL:
            self.results.append((task.task_id, fields['state'], fields['cause']))
            self.queue.pop(0)
            return self.tick(now)
        return None

    def tick(self, now: float) -> dict:
        """Return the head of the queue (or no task) as comms_status."""
        if self.queue:
            return {'comms_status': self.queue[0].record()}
        return {'comms_status': Task('', 'none').record()}
