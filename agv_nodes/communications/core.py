"""Communications: tasks in from people and programs, reports out (Baker 3.3, 3.5.3, 7.2).

It parses the task text (syntax only; the task language: docs/tasks.md), queues the tasks, passes
the head of the queue to the executive as a comms_status record without interpreting it, and turns
the executive's comms_command records into readable reports. A bad task is rejected with the column
and the reason, and changes nothing.
"""

from dataclasses import dataclass, field
import re
from typing import Any

from agv_nodes.settings import settings_class
from agv_nodes.subsystem import SubsystemCore


@settings_class
class CommsParams:
    """The task queue and its relay to the executive (its parameters.yaml section)."""


class TaskError(ValueError):
    """A task text that does not parse; names the column and the reason."""

    def __init__(self, text: str, column: int, reason: str) -> None:
        self.text, self.column, self.reason = text, column, reason
        super().__init__(f'rejected {text!r}: column {column}: {reason}')


@dataclass
class Task:
    """One parsed task, as the comms_status record carries it."""

    text: str
    op: str
    location: int = 0xFF
    marker: str = 'first'
    destination: int = 0xFF
    dwell: int = 0
    srm_angle: int = 0
    then: str = 'stay'
    conveyor: str = 'first'
    load_name: str = ''
    task_id: int = 0

    def record(self) -> dict[str, Any]:
        """Return the comms_status fields."""
        return {'task_id': self.task_id, 'op': self.op, 'location': self.location,
                'marker': self.marker, 'destination': self.destination, 'dwell': self.dwell,
                'srm_angle': self.srm_angle, 'then': self.then, 'conveyor': self.conveyor}


@dataclass
class _Tokens:
    text: str
    items: list[tuple[str, int]] = field(default_factory=list)  # (word, 1-based column)
    i: int = 0

    def __post_init__(self) -> None:
        self.items = [(m.group(0).lower(), m.start() + 1) for m in re.finditer(r'\S+', self.text)]

    def peek(self) -> str | None:
        return self.items[self.i][0] if self.i < len(self.items) else None

    def column(self) -> int:
        return self.items[self.i][1] if self.i < len(self.items) else len(self.text) + 1

    def take(self, *expected: str) -> str:
        word = self.peek()
        if word is None or (expected and word not in expected):
            got = 'the end of the task' if word is None else repr(word)
            raise TaskError(self.text, self.column(),
                            f'expected {" or ".join(repr(e) for e in expected)}, got {got}')
        self.i += 1
        return word

    def number(self, what: str, lo: int, hi: int) -> int:
        column, word = self.column(), self.peek()
        if word is None or not re.fullmatch(r'[+-]?\d+', word):
            got = 'the end of the task' if word is None else repr(word)
            raise TaskError(self.text, column, f'expected {what} (a number), got {got}')
        self.i += 1
        value = int(word)
        if not lo <= value <= hi:
            raise TaskError(self.text, column, f'{what} {value} outside {lo}..{hi}')
        return value


def parse_task(text: str, locations: tuple[int, ...] = (0, 1, 2, 3)) -> Task:
    """Parse one task of the task language (TaskError on anything else)."""
    t = _Tokens(text)
    verb = t.peek()
    verbs = ('load', 'unload', 'wait', 'stop', 'srm', 'leave', 'abort', 'status')
    if verb not in verbs:
        what = 'empty task' if verb is None else f'unknown task {verb!r}'
        raise TaskError(text, t.column(), f'{what} (expected one of {", ".join(verbs)})')
    t.take()

    def location(what: str = 'location') -> int:
        column = t.column()
        n = t.number(what, 0, 31)
        if n not in locations:
            raise TaskError(text, column, f'{what} {n}: no such location marker (known: '
                            f'{", ".join(map(str, locations))})')
        return n

    if verb in ('abort', 'status'):
        task = Task(text, verb)
    elif verb == 'load' and t.peek() not in (None, 'at'):  # load A at B and take to C
        name = t.take()
        t.take('at')
        source = location()
        for word in ('and', 'take', 'to'):
            t.take(word)
        destination = location('destination')
        if destination == source:
            raise TaskError(text, t.items[t.i - 1][1], 'destination equals the source')
        task = Task(text, 'transfer', location=source, destination=destination, load_name=name)
    elif verb in ('srm', 'leave'):
        if verb == 'leave':
            t.take('wire')
        t.take('at')
        n = location()
        angle = 15
        if t.peek() == 'angle':
            t.take()
            angle = t.number('angle', -45, 45)
        task = Task(text, 'srm', location=n, srm_angle=angle, then='continue')
    else:  # load, unload, wait, stop
        t.take('at')
        task = Task(text, verb, location=location())
        if verb == 'wait':
            t.take('for')
            task.dwell = t.number('seconds', 0, 255)
            if t.peek() in ('s', 'sec', 'seconds'):
                t.take()
        if t.peek() in ('first', 'second'):
            task.marker = t.take()
            if task.marker == 'first' and t.peek() == 'then' and t.i + 1 < len(t.items) \
                    and t.items[t.i + 1][0] == 'second':
                t.take('then')
                t.take('second')
                if verb != 'stop':
                    raise TaskError(text, t.items[t.i - 1][1], '"first then second" is a '
                                    'stop task (thesis 7.2 task 6)')
                task.marker = 'first_then_second'
            task.conveyor = 'second' if task.marker == 'second' else 'first'
        if t.peek() == 'then':
            t.take()
            task.then = t.take('continue', 'stay')
    if t.peek() is not None:
        raise TaskError(text, t.column(), f'unexpected {t.peek()!r} after a complete task')
    return task


STATE_WORDS = {'accepted': 'accepted', 'running': 'running', 'step_done': 'step done',
               'completed': 'completed', 'failed': 'FAILED', 'rejected': 'rejected'}


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
            self.notes.add(now, f'task {task.task_id} abort: queue of {len(self.queue)} dropped')
            self.queue = [task]
        else:
            self.queue.append(task)
            self.notes.add(now, f'task {task.task_id} queued: {text!r} ({len(self.queue)} in '
                                f'queue)')
        return self.tick(now)

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """comms_command: the executive's word on a task."""
        key = (fields['task_id'], fields['state'], fields['step'], fields['cause'])
        if key == self._last or not self.queue or fields['task_id'] != self.queue[0].task_id:
            return None
        self._last = key
        task = self.queue[0]
        words = STATE_WORDS.get(fields['state'], fields['state'])
        line = f'task {task.task_id} {task.text!r}: {words}'
        if fields['state'] in ('running', 'step_done'):
            line += f' (step {fields["step"]})'
        if fields['cause'] != 'none':
            line += f': {fields["cause"].replace("_", " ")}'
            if fields['subsystem'] != 'none':
                line += f' ({fields["subsystem"]})'
        if fields['location'] != 0xFF:
            line += f' [last marker L{fields["location"]}]'
        self.notes.add(now, line)
        if fields['state'] in ('completed', 'failed', 'rejected'):
            self.results.append((task.task_id, fields['state'], fields['cause']))
            self.queue.pop(0)
            return self.tick(now)
        return None

    def tick(self, now: float) -> dict:
        """Return the head of the queue (or no task) as comms_status."""
        if self.queue:
            return {'comms_status': self.queue[0].record()}
        return {'comms_status': Task('', 'none').record()}
