"""Communications: tasks in from people and programs, reports out (Baker 3.3, 3.5.3, 7.2).

It parses the task text (syntax only; the task language: docs/tasks.md), queues the tasks, passes
the head of the queue to the executive as a comms_status record without interpreting it, and turns
the executive's comms_command records into readable reports. A bad task is rejected with the column
and the reason, and changes nothing.

Input is bounded (docs/tasks.md, "Limits"): a task longer than `max_task_length` characters is
refused unread, and one that finds `max_queue` tasks queued is refused; each refusal has its
report line. Every message taken from comms/task is counted (`counts`, shown on /diagnostics by
the node), and so are the messages of a writer that never reached it (`on_task`'s `sequence`).

Task numbers: each task taken into the queue gets the next number, 1, 2, 3, ... without end, and
the report lines name it. The comms_status record has 8 bits for it (msg_schemas: 1-255, 0 = no
task), so the record carries the number's residue (`record_id`): 255 wraps to 1. The executive
tells a new task by a changed record id, and communications matches the executive's word to the
head of its queue; both need only the ids of the tasks queued at once, and of the abort that
replaces them, to differ, which a queue of at most 254 guarantees.

Pause (modern: VDA 5050 startPause / stopPause): `pause` and `resume` are commands, not tasks,
counted as `pauses`. Communications holds the pause and sends it in every comms_status
(`paused`), with whatever task heads the queue; the executive brings the truck to rest and keeps
the task. The executive's word on it (comms_command `pause`) becomes a line of its own each time
it changes (report_line.PAUSE_WORDS), as the truck, not the request, is what a master is told.
"""

from collections import Counter
from typing import Any

from agv_nodes.communications.report_line import (
    FINAL,
    abort_line,
    pause_line,
    progress_line,
    queued_line,
)
from agv_nodes.communications.task_language import Task, TaskError, parse_task
from agv_nodes.records import codec
from agv_nodes.records.ports import DUPLICATE_WRITER
from agv_nodes.settings import settings_class
from agv_nodes.subsystem import SubsystemCore

RECORD_IDS = codec()['comms_status'].field('task_id').hi  # 255: the record's ids are 1..255
# What `counts` counts, in /diagnostics order: every message taken is exactly one of the first
# seven; `lost` are messages a writer sent that never reached communications.
COUNTS = ('queued', 'aborts', 'queries', 'pauses', 'rejected', 'refused too long',
          'refused queue full', 'lost')


@settings_class
class CommsParams:
    """The task queue and its relay to the executive (its parameters.yaml section)."""


def record_id(number: int) -> int:
    """Return the comms_status task_id of task `number` (1, 2, ... 255, 1, 2, ...)."""
    return (number - 1) % RECORD_IDS + 1


class CommunicationsCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'communications', CommsParams, 'period'

    def __init__(self, params: CommsParams | None = None) -> None:
        super().__init__(params)
        self.queue: list[Task] = []
        self.results: list[tuple[int, str, str]] = []  # (task number, final state, cause)
        self.counts: Counter[str] = Counter(dict.fromkeys(COUNTS, 0))
        self._next_number = 1
        self._last: tuple | None = None
        self._sequence: dict[Any, int] = {}  # writer -> its last sequence number taken
        self.paused = False  # asked by `pause`, until `resume`
        self._pause = 'none'  # the executive's last word on it (comms_command pause)

    def on_task(self, text: str, now: float, writer: Any = None,
                sequence: int | None = None) -> dict | None:
        """Take a task from comms/task.

        `writer` and `sequence` (when known) are the message's writer and its number among that
        writer's messages: a gap since the writer's last one is messages lost on the way.
        """
        if sequence is not None:
            self._count_lost(writer, sequence, now)
        if len(text) > self.p.max_task_length:
            self.counts['refused too long'] += 1
            self.notes.add(now, f'comms: refused a task of {len(text)} characters (more than '
                                f'max_task_length {self.p.max_task_length})', 'warn')
            return None
        try:
            task = parse_task(text, self.p.locations)
        except TaskError as exc:
            self.counts['rejected'] += 1
            self.notes.add(now, f'comms: {exc}')
            return None
        if task.op == 'status':  # a query: answered, never queued (demo.py's handshake)
            self.counts['queries'] += 1
            head = f'; head: task {self.queue[0].number} {self.queue[0].text!r}' \
                if self.queue else ''
            self.notes.add(now, f'comms: status: {len(self.queue)} in queue{head}')
            return None
        if task.op in ('pause', 'resume'):  # a command: held, never queued
            self.counts['pauses'] += 1
            self.paused = task.op == 'pause'
            head = f'; task {self.queue[0].number} kept' if self.queue else ''
            self.notes.add(now, f'comms: {task.op}: sent to the executive ({len(self.queue)} in '
                                f'queue{head})')
            return self.tick(now)
        # an abort is never refused: it stops the truck and replaces the queue
        if task.op != 'abort' and len(self.queue) >= self.p.max_queue:
            self.counts['refused queue full'] += 1
            self.notes.add(now, f'comms: refused {text!r}: queue full ({len(self.queue)} '
                                f'tasks, max_queue {self.p.max_queue})', 'warn')
            return None
        task.number = self._next_number
        task.task_id = record_id(task.number)
        self._next_number += 1
        if task.op == 'abort':
            self.counts['aborts'] += 1
            self.notes.add(now, abort_line(task.number, len(self.queue)))
            self.queue = [task]
        else:
            self.counts['queued'] += 1
            self.queue.append(task)
            self.notes.add(now, queued_line(task.number, text, len(self.queue)))
        return self.tick(now)

    def _count_lost(self, writer: Any, sequence: int, now: float) -> None:
        last = self._sequence.get(writer)
        self._sequence[writer] = sequence
        if last is not None and sequence > last + 1:
            lost = sequence - last - 1
            self.counts['lost'] += lost
            self.notes.add(now, f'comms: {lost} task messages lost before communications read '
                                f'them (its reader fell behind the writer)', 'warn')

    def on_reject(self, record: str, reason: str, now: float) -> dict | None:
        """Fail the head task when two live executives both write comms_command.

        Neither's word can be relayed (records.writer_check rejects both), and a report that
        says nothing would leave its sender waiting: the line names the duplicate instead.
        """
        if reason != DUPLICATE_WRITER or not self.queue:
            return None
        task = self.queue.pop(0)
        self.notes.add(now, progress_line(task.number, task.text, {
            'state': 'failed', 'step': 0, 'cause': DUPLICATE_WRITER, 'subsystem': 'executive',
            'location': 0xFF}), 'warn')
        self.results.append((task.number, 'failed', DUPLICATE_WRITER))
        return self.tick(now)

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """comms_command: the executive's word on a task."""
        pause = fields.get('pause', 'none')
        if pause != self._pause:  # the truck's pause, whatever task it is about
            self._pause = pause
            self.notes.add(now, pause_line(pause))
        # the location too: a line for each location marker passed tells a master control
        # (the VDA 5050 bridge) which node the truck has reached
        key = (fields['task_id'], fields['state'], fields['step'], fields['cause'],
               fields['location'])
        if key == self._last or not self.queue or fields['task_id'] != self.queue[0].task_id:
            return None
        self._last = key
        task = self.queue[0]
        line = progress_line(task.number, task.text, fields)
        self.notes.add(now, line)
        if fields['state'] in FINAL:
            self.results.append((task.number, fields['state'], fields['cause']))
            self.queue.pop(0)
            return self.tick(now)
        return None

    def tick(self, now: float) -> dict:
        """Return the head of the queue (or no task) as comms_status."""
        task = self.queue[0] if self.queue else Task('', 'none')
        return {'comms_status': {**task.record(), 'paused': int(self.paused)}}

    def task_report(self, refused_before: int = 0) -> tuple[int, str, dict[str, str]]:
        """Return the task counts for /diagnostics: (level 0 OK / 1 WARN, message, values).

        WARN while tasks are being refused or lost (more than `refused_before` in all).
        """
        values = {k: str(self.counts[k]) for k in COUNTS}
        values |= {'in queue': str(len(self.queue)), 'writers': str(len(self._sequence)),
                   'max_queue': str(self.p.max_queue),
                   'max_task_length': str(self.p.max_task_length)}
        refused = self.refused_or_lost()
        level = 1 if refused > refused_before else 0
        message = (f'{len(self.queue)} in queue; {self.counts["queued"]} queued, '
                   f'{self.counts["refused too long"] + self.counts["refused queue full"]} '
                   f'refused, {self.counts["lost"]} lost in all')
        return level, message, values

    def refused_or_lost(self) -> int:
        """Return the task messages refused or lost so far."""
        return sum(self.counts[k] for k in ('refused too long', 'refused queue full', 'lost'))
