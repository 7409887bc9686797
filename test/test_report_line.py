"""comms/report lines: written by communications, read back by a program directing the truck."""

from __future__ import annotations

import pytest

from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.communications.report_line import (
    Aborted,
    Progress,
    Queued,
    abort_line,
    progress_line,
    queued_line,
    read_report,
)

pytestmark = pytest.mark.timeout(30)

NONE = {'cause': 'none', 'subsystem': 'none', 'detail': 'none', 'location': 0xFF, 'step': 0}


@pytest.mark.parametrize('fields, expected', [
    ({**NONE, 'state': 'running', 'location': 2},
     Progress(6, 'load at 1', 'running', 0, '', 2)),
    ({**NONE, 'state': 'step_done', 'step': 1}, Progress(6, 'load at 1', 'step_done', 1)),
    ({**NONE, 'state': 'completed', 'location': 1}, Progress(6, 'load at 1', 'completed', None,
                                                             '', 1)),
    ({**NONE, 'state': 'failed', 'cause': 'lost_wire', 'subsystem': 'route', 'location': 0},
     Progress(6, 'load at 1', 'failed', None, 'lost wire (route)', 0)),
    ({**NONE, 'state': 'failed', 'cause': 'drive_fault', 'subsystem': 'traction',
      'detail': 'over_current'},
     Progress(6, 'load at 1', 'failed', None, 'drive fault (traction): over current')),
    ({**NONE, 'state': 'rejected', 'cause': 'bad_task'},
     Progress(6, 'load at 1', 'rejected', None, 'bad task')),
])
def test_a_progress_line_reads_back_as_written(fields, expected):
    line = progress_line(6, 'load at 1', fields)
    assert read_report(line) == expected, line


def test_queue_and_abort_lines_read_back():
    assert read_report(queued_line(3, 'stop at 2 second', 2)) == Queued(3, 'stop at 2 second', 2)
    assert read_report(queued_line(4, "it's", 1)) == Queued(4, "it's", 1)  # repr with "..."
    assert read_report(abort_line(9, 3)) == Aborted(9, 3)
    assert read_report('comms: status: 0 in queue') is None
    assert read_report("comms: rejected 'x': column 1: unknown task") is None


def test_communications_reports_each_location_marker_passed():
    core = CommunicationsCore()
    core.on_task('load at 1', 0.0)
    for t, location in enumerate((0xFF, 0, 0, 2, 1), start=1):
        core.on_record('comms_command', {**NONE, 'task_id': 1, 'state': 'running',
                                         'location': location}, float(t))
    lines = [read_report(text) for text in core.notes.texts()]
    assert [(p.state, p.last_marker) for p in lines if isinstance(p, Progress)] == [
        ('running', None), ('running', 0), ('running', 2), ('running', 1)]
