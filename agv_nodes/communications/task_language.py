"""The task language: task text into the comms_status record's fields (docs/tasks.md).

Syntax only, as communications passes tasks on without interpreting them (Baker 1983, 3.5.3):
the 1983 tasks of 7.2 and fig 3.1, and the 1991 camera truck's tape legs with their junction
scripts and law (Rajagopalan 1991, App. F.5-F.7) and its dead-reckoning legs along a stored
trajectory (App. F.9), its manual mode driven from cmd_vel (App. F.4, `manual [for T s]`) and its
camera calibration (App. F.3, `calibrate [front|rear]`). `at N [first|second]` is a modern
addition: it tells a truck set down by hand (or by a fleet, VDA 5050 initPosition) at which stop
marker it stands; so are `pause` and `resume` (VDA 5050 startPause / stopPause), commands like
`abort` and `status`, never queued. A text that does not parse raises TaskError naming the
column and the reason.
"""

from dataclasses import dataclass, field
import re
from typing import Any

from agv_nodes.records import codec

SCRIPT_JUNCTIONS = 4  # script lines the comms_status record has room for (bytes 10-12)
DECISIONS = ('straight', 'left', 'right', 'random')
# A tape task's law and a reckon task's trajectory number, as comms_status can carry them.
CAMERA_LAWS = tuple(law for law in codec()['comms_status'].field('camera_law').values
                    if law != 'default')
TRAJECTORIES = codec()['comms_status'].field('trajectory').hi
# A tape leg's steering camera (`camera C`), as comms_status carries it (App. F.2 items 7-8).
CAMERAS = tuple(c for c in codec()['comms_status'].field('camera').values if c != 'default')


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
    task_id: int = 0  # comms_status's 8-bit id of the task (communications.core.record_id)
    number: int = 0  # the task's number in the report lines (1, 2, 3, ... without end)
    # a tape leg: decision and wait per scripted junction, what unscripted ones do, dm of travel
    junctions: dict[int, tuple[str, int]] = field(default_factory=dict)
    unscripted: str = 'straight'
    leg_distance: int = 0
    reverse_distance: int = 0
    camera_law: str = 'default'  # a tape leg's law forwards (default: route following's own)
    trajectory: int = 0  # a reckon leg's stored trajectory (0 = the track identified last)
    camera: str = 'default'  # a tape leg's steering camera (default: route following's own)
    reverse_camera: str = 'default'  # the reverse leg's

    def record(self) -> dict[str, Any]:
        """Return the comms_status fields."""
        out = {'task_id': self.task_id, 'op': self.op, 'location': self.location,
               'marker': self.marker, 'destination': self.destination, 'dwell': self.dwell,
               'srm_angle': self.srm_angle, 'then': self.then, 'conveyor': self.conveyor,
               'unscripted': self.unscripted, 'leg_distance': self.leg_distance,
               'reverse_distance': self.reverse_distance, 'camera_law': self.camera_law,
               'trajectory': self.trajectory, 'camera': self.camera,
               'reverse_camera': self.reverse_camera}
        for n in range(1, SCRIPT_JUNCTIONS + 1):
            decision, wait = self.junctions.get(n, (self.unscripted, 0))
            out[f'junction_{n}'], out[f'wait_{n}'] = decision, wait
        return out


@dataclass
class _Tokens:
    text: str
    items: list[tuple[str, int]] = field(default_factory=list)  # (word, 1-based column)
    i: int = 0

    def __post_init__(self) -> None:
        words = re.finditer(r'[^\s,]+|,', self.text)  # a comma is a word of its own
        self.items = [(m.group(0).lower(), m.start() + 1) for m in words]

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

    def decimetres(self, what: str) -> int:
        """`D m` (or `D`), D in metres with up to one decimal: whole dm, 1..255."""
        column, word = self.column(), self.peek()
        if word is None or not re.fullmatch(r'\d+(\.\d)?', word):
            got = 'the end of the task' if word is None else repr(word)
            raise TaskError(self.text, column, f'expected {what} in m (e.g. 2.5), got {got}')
        self.i += 1
        dm = round(float(word) * 10)
        if not 1 <= dm <= 255:
            raise TaskError(self.text, column, f'{what} {word} m outside 0.1..25.5')
        if self.peek() in ('m', 'metres', 'meters'):
            self.take()
        return dm


def parse_task(text: str, locations: tuple[int, ...] = (0, 1, 2, 3)) -> Task:
    """Parse one task of the task language (TaskError on anything else)."""
    t = _Tokens(text)
    verb = t.peek()
    verbs = ('load', 'unload', 'wait', 'stop', 'srm', 'leave', 'at', 'pass', 'tape', 'reckon',
             'manual', 'calibrate', 'abort', 'status', 'pause', 'resume')
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

    if verb in ('abort', 'status', 'pause', 'resume'):  # pause, resume: commands (modern)
        task = Task(text, verb)
    elif verb == 'tape':
        task = _tape(t)
    elif verb == 'reckon':
        task = _reckon(t)
    elif verb == 'manual':  # manual [for T s]: cmd_vel drives (App. F.4); no T: until an abort
        task = Task(text, 'manual')
        if t.peek() == 'for':
            t.take()
            task.dwell = t.number('seconds', 1, 255)
            if t.peek() in ('s', 'sec', 'seconds'):
                t.take()
    elif verb == 'calibrate':  # calibrate [front|rear]: the camera read at rest (App. F.3)
        task = Task(text, 'calibrate')
        if t.peek() in ('front', 'rear'):
            task.then = 'reverse' if t.take() == 'rear' else 'stay'
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
    elif verb == 'at':  # at N [first|second]: where the truck stands (modern)
        task = Task(text, 'at', location=location())
        if t.peek() in ('first', 'second'):
            task.marker = t.take()
    elif verb == 'pass':  # pass N: on past the next marker of location N (modern)
        task = Task(text, 'pass', location=location(), then='continue')
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


def _tape(t: _Tokens) -> Task:
    """Parse `tape [with LAW] [camera C] [junctions ...] [for D m] [then reverse [camera C] ...]`.

    In full: `tape [with LAW] [camera C] [junctions SCRIPT | junctions random] [for D m] [then
    reverse [camera C] [for D m]]`. LAW: feedback or feed_forward, the leg's law going
    forwards (App. F.5's keys chose it); without `with`, route following's camera_law
    parameter (or the layout's). SCRIPT: `N DECISION [wait S]` items, comma-separated, N the
    N-th junction met on the leg (Rajagopalan 1991, App. F.7: junction number, decision, wait
    time), optionally followed by `otherwise straight|random` for the junctions it does not
    name. C: the leg's steering camera, auto, front, rear or both (App. F.2 items 7-8);
    without it, route following's camera_select.
    """
    task = Task(t.text, 'tape')
    if t.peek() == 'with':
        t.take()
        task.camera_law = t.take(*CAMERA_LAWS)
    if t.peek() == 'camera':
        t.take()
        task.camera = t.take(*CAMERAS)
    if t.peek() == 'junctions':
        t.take()
        if t.peek() == 'random':
            t.take()
            task.unscripted = 'random'
        else:
            while True:
                column = t.column()
                n = t.number('junction number', 1, SCRIPT_JUNCTIONS)
                if n in task.junctions:
                    raise TaskError(t.text, column, f'junction {n} scripted twice')
                decision = t.take(*DECISIONS)
                wait = 0
                if t.peek() == 'wait':
                    t.take()
                    wait = t.number('seconds', 0, 15)
                    if t.peek() in ('s', 'sec', 'seconds'):
                        t.take()
                task.junctions[n] = (decision, wait)
                if t.peek() != ',':
                    break
                t.take()
            if t.peek() == 'otherwise':
                t.take()
                task.unscripted = t.take('straight', 'random')
    if t.peek() == 'for':
        t.take()
        task.leg_distance = t.decimetres('leg length')
    if t.peek() == 'then':
        t.take()
        task.then = t.take('reverse')
        if t.peek() == 'camera':
            t.take()
            task.reverse_camera = t.take(*CAMERAS)
        if t.peek() == 'for':
            t.take()
            task.reverse_distance = t.decimetres('reverse length')
    return task


def _reckon(t: _Tokens) -> Task:
    """`reckon (trajectory N | track) for D m`: a dead-reckoning leg (Rajagopalan 1991, App. F.9).

    Without the camera, along stored trajectory N (route following's dead_reckoning.trajectories)
    placed at the truck's pose, or along the track it identified last; the length is required,
    since nothing but the distance ends the leg.
    """
    task = Task(t.text, 'reckon')
    if t.take('trajectory', 'track') == 'trajectory':
        task.trajectory = t.number('trajectory', 1, TRAJECTORIES)
    t.take('for')
    task.leg_distance = t.decimetres('reckon length')
    return task
