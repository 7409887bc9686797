"""A duplicate writer reaches the cores as a rejection, reason duplicate_writer: each stops, named.

ROS-free. The readers (records.writer_check.WriterCheck, test_records_writer_check.py) tell a
node's core of every record of two live writers as `on_reject(record, 'duplicate_writer', t)`
(agv_nodes/ros_ports.py, core_node.py). What each core must then do, and the record fields
that carry it, are judged against the record tables in msg_schemas/ (the codec encodes only
values the tables have): traction opens its trip relay for any of its inputs; the executive
fails a running task naming the sub-system whose status is duplicated, or traction for
traction's own trip; communications fails the head task naming the executive.
test_duplicate_writer_dds.py shows the whole path over DDS with a second executive.
"""

from __future__ import annotations

import pytest

from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.harness import submit, truck
from agv_nodes.records import codec
from agv_nodes.records.ports import DUPLICATE_WRITER
from agv_nodes.traction.core import TractionCore

pytestmark = pytest.mark.timeout(120)

TRACTION_INPUTS = sorted(s.name for s in codec() if 'traction' in s.readers)


def armed_traction() -> TractionCore:
    """Traction with its relay closed: 00H, then a demand (its reset rule)."""
    core = TractionCore()
    command = codec()['traction_command'].decode(codec()['traction_command'].encode())
    for t, demand in ((0.0, 0), (0.05, 30)):
        core.on_record('traction_command', {**command, 'demand': demand}, t)
        core.tick(t)
    assert not core.tripped
    return core


@pytest.mark.parametrize('record', TRACTION_INPUTS)
def test_a_duplicate_writer_of_any_traction_input_opens_the_trip_relay_at_once(record):
    core = armed_traction()
    out = core.on_reject(record, DUPLICATE_WRITER, 0.1)
    drive = out['traction_drive']  # at once, not at the next loop pass
    assert drive['contactor'] == 0 and drive['armature_duty'] == 0, drive
    status = core.status()
    assert status['trip_cause'] == 'duplicate_writer' and status['tripped'] == 1
    schema = codec()['traction_status']
    assert schema.decode(schema.encode(status))['trip_cause'] == 'duplicate_writer'
    assert core.health() == (2, 'trip relay open: duplicate_writer (two writers of one input: '
                                'its row names them)')


def test_another_rejection_reason_is_no_duplicate():
    core = armed_traction()
    assert core.on_reject('wheel_odometry', 'foreign_writer', 0.1) is None
    assert not core.tripped


@pytest.fixture(scope='module')
def cruising():
    """Return the lock-step demo truck cruising its task (the executive running)."""
    h = truck('demo_1983', seed=1)
    submit(h, 'stop at 2 second')
    h.run(20.0, until=lambda: h.world.vehicle.state.speed > 0.5)
    return h


@pytest.mark.parametrize('record, subsystem', [('navigation_status', 'navigation'),
                                               ('route_status', 'route'),
                                               ('traction_status', 'traction')])
def test_the_executive_fails_the_task_naming_a_duplicated_status(record, subsystem):
    h = truck('demo_1983', seed=1)
    submit(h, 'stop at 2 second')
    h.run(20.0, until=lambda: h.world.vehicle.state.speed > 0.5)
    executive = h.cores['executive']
    out = executive.on_reject(record, DUPLICATE_WRITER, h.now)
    assert executive.fault == ('duplicate_writer', subsystem)
    assert out['traction_command']['demand'] == 0  # the emergency stop, at once
    report = out['comms_command']
    schema = codec()['comms_command']
    assert schema.decode(schema.encode(report))['cause'] == 'duplicate_writer'
    assert report['state'] == 'failed' and report['subsystem'] == subsystem


def test_the_executive_names_a_trip_of_traction_on_a_duplicate(cruising):
    executive = cruising.cores['executive']
    status = dict(executive.status['traction'], tripped=1, trip_cause='duplicate_writer')
    executive.on_record('traction_status', status, cruising.now)
    executive.supervise(cruising.now)
    assert executive.fault == ('duplicate_writer', 'traction')


def test_communications_fails_the_head_task_naming_the_executive():
    comms = CommunicationsCore()
    comms.on_task('stop at 2 second', 0.0)
    comms.notes.take()
    out = comms.on_reject('comms_command', DUPLICATE_WRITER, 0.1)
    lines = [n.text for n in comms.notes.take()]
    assert lines == ["task 1 'stop at 2 second': FAILED: duplicate writer (executive)"], lines
    assert not comms.queue and out['comms_status']['task_id'] == 0
    assert comms.on_reject('comms_command', DUPLICATE_WRITER, 0.2) is None  # nothing queued
