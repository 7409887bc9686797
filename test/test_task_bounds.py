"""Bounded task input (communications, ROS-free): too long, queue full, task numbers past 255.

The limits are the parameter file's (agv_nodes/communications/parameters.yaml, read here as
YAML); the record's id range is msg_schemas' comms_status table. Over DDS:
test_task_flood_dds.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from agv_nodes.communications.core import CommsParams, CommunicationsCore
from agv_nodes.communications.report_line import Queued, read_report
from agv_nodes.settings import SettingError, build

pytestmark = pytest.mark.timeout(60)

REPO = Path(__file__).resolve().parent.parent
DECLARED = yaml.safe_load((REPO / 'agv_nodes' / 'communications' / 'parameters.yaml')
                          .read_text())['CommsParams']
MAX_LENGTH = DECLARED['max_task_length']['default']
MAX_QUEUE = DECLARED['max_queue']['default']
TASK_ID = next(f for f in yaml.safe_load((REPO / 'msg_schemas' / 'comms_status.yaml')
                                         .read_text())['fields'] if f['name'] == 'task_id')
RECORD_IDS = 2 ** 8 - 1  # task_id is byte 1 of comms_status, 0 = no task
NONE = {'cause': 'none', 'subsystem': 'none', 'detail': 'none', 'location': 0xFF, 'step': 0}


def test_the_declared_limits_fit_the_record_and_the_thesis():
    assert 'byte' in TASK_ID and 'bits' not in TASK_ID, TASK_ID  # a whole byte
    assert TASK_ID['units'].startswith(f'task number, 1-{RECORD_IDS}'), TASK_ID
    # the queued tasks plus an abort replacing them need distinct ids: a queue of 254 at most
    assert DECLARED['max_queue']['range'] == [1, RECORD_IDS - 1]
    assert 1 <= MAX_QUEUE <= RECORD_IDS - 1
    assert len('load A at 1 and take to 3') < MAX_LENGTH  # the thesis's longest task
    with pytest.raises(SettingError):
        build(CommsParams, {'max_queue': RECORD_IDS})


def test_a_task_longer_than_the_limit_is_refused_without_its_text():
    comms = CommunicationsCore()
    fits = 'stop at 2 first'.ljust(MAX_LENGTH)  # parses: blanks are not words
    assert comms.on_task(fits, 0.0) is not None and len(comms.queue) == 1
    before = comms.tick(0.1)
    for text in ('stop at 2 first'.ljust(MAX_LENGTH + 1), 'x' * (1 << 20)):
        assert comms.on_task(text, 0.2) is None
        line = comms.notes.texts()[-1]
        assert line == (f'comms: refused a task of {len(text)} characters (more than '
                        f'max_task_length {MAX_LENGTH})'), line[:200]
    assert comms.tick(0.3) == before and len(comms.queue) == 1
    assert comms.counts['refused too long'] == 2 and comms.counts['queued'] == 1
    level, _message, values = comms.task_report()
    assert level == 1 and values['refused too long'] == '2'


def test_a_full_queue_refuses_each_task_with_a_line_but_never_an_abort():
    comms = CommunicationsCore()
    for k in range(MAX_QUEUE):
        comms.on_task(f'wait at 1 for {k} s', float(k))
    head = comms.tick(100.0)
    for k in range(3):
        assert comms.on_task(f'stop at {k} first', 100.0) is None
        assert comms.notes.texts()[-1] == (f"comms: refused 'stop at {k} first': queue full "
                                           f'({MAX_QUEUE} tasks, max_queue {MAX_QUEUE})')
    assert comms.tick(101.0) == head and len(comms.queue) == MAX_QUEUE
    comms.on_task('status', 102.0)
    assert comms.notes.texts()[-1].startswith(f'comms: status: {MAX_QUEUE} in queue')
    out = comms.on_task('abort', 103.0)
    assert out['comms_status']['op'] == 'abort' and len(comms.queue) == 1
    assert comms.notes.texts()[-1] == f'task {MAX_QUEUE + 1} abort: queue of {MAX_QUEUE} dropped'
    assert dict(comms.counts) == {
        'queued': MAX_QUEUE, 'aborts': 1, 'queries': 1, 'pauses': 0, 'rejected': 0,
        'refused too long': 0, 'refused queue full': 3, 'lost': 0}


def _complete_head(comms: CommunicationsCore, t: float) -> dict:
    """Play the executive: complete the task at the head of the queue."""
    head = comms.tick(t)['comms_status']
    return comms.on_record('comms_command', {**NONE, 'task_id': head['task_id'],
                                             'state': 'completed'}, t)


def test_task_numbers_go_on_past_255_and_the_record_ids_of_successive_heads_differ():
    comms = CommunicationsCore()
    heads = []  # the record ids the executive sees, in order
    for k in range(600):
        text = f'wait at {k % 4} for {k % 256} s'
        comms.on_task(text, float(k))
        if k % 3 == 2:  # the queue grows and drains: tasks wait behind others
            while comms.queue:
                heads.append(comms.tick(float(k))['comms_status']['task_id'])
                _complete_head(comms, float(k))
    queued = [r for r in map(read_report, comms.notes.texts()) if isinstance(r, Queued)]
    assert [q.task_id for q in queued][-100:] == list(range(501, 601))  # read back, no wrap
    assert [number for number, _, _ in comms.results] == list(range(1, 601))
    assert all(1 <= h <= RECORD_IDS for h in heads)
    assert heads == [(n - 1) % RECORD_IDS + 1 for n in range(1, 601)]  # the record wraps
    assert all(a != b for a, b in zip(heads, heads[1:], strict=False))


def test_an_abort_at_the_largest_queue_has_an_id_of_its_own():
    """254 queued, an abort: its record id differs from the running head's (255 would not)."""
    comms = CommunicationsCore(build(CommsParams, {'max_queue': RECORD_IDS - 1}))
    for k in range(RECORD_IDS + 3):  # numbers 1..258: the ids wrap once
        comms.on_task('stop at 2 first', float(k))
        _complete_head(comms, float(k))
    for _ in range(RECORD_IDS - 1):
        comms.on_task('stop at 2 first', 300.0)
    head = comms.tick(300.0)['comms_status']['task_id']
    assert comms.on_task('stop at 1 first', 300.0) is None  # full
    abort = comms.on_task('abort', 301.0)['comms_status']['task_id']
    assert abort != head and (abort - head) % RECORD_IDS == RECORD_IDS - 1


def test_messages_lost_on_the_way_are_counted_per_writer():
    comms = CommunicationsCore()
    a, b = b'writer-a', b'writer-b'
    # each writer's first message seen starts its count (earlier ones went before it matched)
    for writer, sequence in ((a, 7), (b, 1), (a, 8), (b, 2), (a, 12), (b, 6), (a, 13)):
        comms.on_task('status', float(sequence), writer, sequence)
    assert comms.counts['lost'] == 3 + 3
    lost_lines = [t for t in comms.notes.texts() if 'lost' in t]
    assert lost_lines == ['comms: 3 task messages lost before communications read them (its '
                          'reader fell behind the writer)'] * 2
    level, message, values = comms.task_report()
    assert level == 1 and values['lost'] == '6' and values['writers'] == '2'
    assert comms.task_report(refused_before=6)[0] == 0  # nothing new since: OK again
