"""The lines communications writes on comms/report, and their reading back.

The radio link of Baker 1983 (3.3) carried text both ways; so does comms/report. People read the
lines, and a program that directs the truck through it (the VDA 5050 bridge) reads them with
`read_report`, so the one format lives here, written and read by the same module:

    task 6 queued: 'load at 1' (1 in queue)
    task 7 abort: queue of 2 dropped
    task 6 'load at 1': running (step 0) [last marker L2]
    task 6 'load at 1': FAILED: lost wire (route) [last marker L0]
    truck paused: at rest until resume

The last kind is the executive's pause (comms_command `pause`, a modern addition for VDA 5050
startPause / stopPause), one line each time it changes, whatever task runs.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
import re

STATE_WORDS = {'accepted': 'accepted', 'running': 'running', 'step_done': 'step done',
               'completed': 'completed', 'failed': 'FAILED', 'rejected': 'rejected'}
_STATES = {words: state for state, words in STATE_WORDS.items()}
FINAL = ('completed', 'failed', 'rejected')
# The executive's pause (comms_command `pause`), as the line that says it changed.
PAUSE_WORDS = {'none': 'truck resumed: it drives as its task asks',
               'stopping': 'truck pausing: coming to rest, its task kept',
               'paused': 'truck paused: at rest until resume',
               'unable': 'truck cannot pause: its executive has no pause for this guidance'}
_PAUSES = {words: pause for pause, words in PAUSE_WORDS.items()}

_TEXT = r"('(?:[^'\\]|\\.)*'|\"(?:[^\"\\]|\\.)*\")"  # a Python repr of the task text
_QUEUED = re.compile(rf'^task (\d+) queued: {_TEXT} \((\d+) in queue\)$')
_ABORT = re.compile(r'^task (\d+) abort: queue of (\d+) dropped$')
_PROGRESS = re.compile(rf'^task (\d+) {_TEXT}: ({"|".join(map(re.escape, _STATES))})'
                       r'(?: \(step (\d+)\))?(?:: (.*?))?(?: \[last marker L(\d+)\])?$')


@dataclass(frozen=True)
class Queued:
    """A task taken into the queue under the id communications gave it."""

    task_id: int
    text: str
    in_queue: int


@dataclass(frozen=True)
class Aborted:
    """An abort: it heads the queue at once, and what was queued is dropped."""

    task_id: int
    dropped: int


@dataclass(frozen=True)
class Paused:
    """The executive's pause changed: none, stopping, paused or unable (comms_command)."""

    pause: str


@dataclass(frozen=True)
class Progress:
    """The executive's word on a task (comms_command), as one line."""

    task_id: int
    text: str
    state: str  # a comms_command state: running, step_done, completed, failed, ...
    step: int | None = None
    cause: str = ''  # 'lost wire (route)', with the sub-system and any detail
    last_marker: int | None = None

    @property
    def final(self) -> bool:
        """Return True for the task's last line (completed, failed or rejected)."""
        return self.state in FINAL


def queued_line(task_id: int, text: str, in_queue: int) -> str:
    """Return the line for a task taken into the queue."""
    return f'task {task_id} queued: {text!r} ({in_queue} in queue)'


def abort_line(task_id: int, dropped: int) -> str:
    """Return the line for an abort."""
    return f'task {task_id} abort: queue of {dropped} dropped'


def pause_line(pause: str) -> str:
    """Return the line for the executive's pause `pause` (a comms_command `pause` value)."""
    return PAUSE_WORDS[pause]


def no_branch_text(junction: int, flags: tuple[int, int, int], decision: str) -> str:
    """Return what a no_branch was: the junction, the sign seen, its branches, the decision.

    `flags`: the sign's (left, right, straight) branch flags (Rajagopalan 1991, fig 4.3).
    """
    # Fig. 4.3's decoding, imported only for a no_branch: the reader otherwise needs no numpy.
    from agv_nodes.route_following.camera_guidance import sign_name

    offered = [way for way, flag in zip(('left', 'right', 'straight'), flags, strict=True)
               if flag] or ['none']
    return (f'junction {junction}: sign {sign_name(*flags) or "unread"} seen, '
            f'offering {" and ".join(offered)}; the decision {decision} is not on it')


def progress_line(task_id: int, text: str, fields: dict) -> str:
    """Return the line for a comms_command record about task `task_id`."""
    line = f'task {task_id} {text!r}: {STATE_WORDS.get(fields["state"], fields["state"])}'
    if fields['state'] in ('running', 'step_done'):
        line += f' (step {fields["step"]})'
    if fields['cause'] != 'none':
        line += f': {fields["cause"].replace("_", " ")}'
        if fields['subsystem'] != 'none':
            line += f' ({fields["subsystem"]})'
        if fields.get('detail', 'none') != 'none':  # which drive fault
            line += f': {fields["detail"].replace("_", " ")}'
        if fields['cause'] == 'no_branch' and fields.get('junction', 0):
            line += ': ' + no_branch_text(
                fields['junction'], tuple(int(fields.get(f'sign_{way}', 0))
                                          for way in ('left', 'right', 'straight')),
                fields.get('decision', 'none'))
    if fields['location'] != 0xFF:
        line += f' [last marker L{fields["location"]}]'
    return line


def read_report(line: str) -> Queued | Aborted | Progress | Paused | None:
    """Return what a comms/report line says about a task or the pause (None: another kind)."""
    if line in _PAUSES:
        return Paused(_PAUSES[line])
    if m := _QUEUED.match(line):
        return Queued(int(m[1]), ast.literal_eval(m[2]), int(m[3]))
    if m := _ABORT.match(line):
        return Aborted(int(m[1]), int(m[2]))
    if m := _PROGRESS.match(line):
        return Progress(int(m[1]), ast.literal_eval(m[2]), _STATES[m[3]],
                        int(m[4]) if m[4] is not None else None, m[5] or '',
                        int(m[6]) if m[6] is not None else None)
    return None
