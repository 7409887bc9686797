"""SentTimeline: a status is aged from when it was sent, not from when a starved reader took it."""

from __future__ import annotations

import pytest
from test_executive_comms_load import status_records

from agv_nodes.communications.task_language import parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.sent_time import SentTimeline

MS = 1_000_000  # ns


def test_sim_at_maps_a_send_to_the_clock_sample_before_it():
    t = SentTimeline()
    assert not t and t.now() == 0.0
    for k in range(10):  # world clock every 10 ms of wall, 8.8 ms of sim
        t.clock(1_000 * MS + k * 10 * MS, 5.0 + k * 0.0088)
    assert t.now() == pytest.approx(5.0 + 9 * 0.0088)
    assert t.sim_at(1_000 * MS + 35 * MS) == pytest.approx(5.0 + 3 * 0.0088)
    assert t.sim_at(1_000 * MS + 30 * MS) == pytest.approx(5.0 + 3 * 0.0088)  # same instant
    assert t.sim_at(2_000 * MS) == t.now()  # sent after the latest sample taken: as new
    assert t.sim_at(990 * MS) == pytest.approx(5.0 - 0.010)  # before the history: wall-aged


def test_a_record_sent_after_the_latest_sample_is_raised_until_a_later_one_arrives():
    t = SentTimeline()
    t.clock(0, 1.0)
    assert t.record('navigation_status', 25 * MS) == 1.0  # the clock queue is behind
    assert t.clock(10 * MS, 1.01) == [('navigation_status', 1.01)]
    assert t.clock(20 * MS, 1.02) == [('navigation_status', 1.02)]
    assert t.clock(30 * MS, 1.03) == []  # sent before this one: 1.02 was final
    assert t.clock(40 * MS, 1.04) == []
    assert t.record('navigation_status', 35 * MS) == 1.03  # placed at once


def test_pause_and_out_of_order_samples():
    t = SentTimeline(keep=1.0)
    t.clock(0, 1.0)
    t.clock(500 * MS, 1.0)  # the world paused: wall time passes, sim time does not
    t.clock(400 * MS, 0.9)  # a late best-effort sample: ignored
    t.clock(600 * MS, 1.1)
    assert t.sim_at(550 * MS) == 1.0 and t.now() == 1.1
    t.clock(2_000 * MS, 2.0)  # keeps one second of wall time
    assert t.sim_at(100 * MS) < 1.1
    t.clock(3_000 * MS, 0.0)  # a respawned world starts again at 0
    assert t.now() == 0.0 and t.sim_at(3_500 * MS) == 0.0


def cruising(sent: bool, stale_confirm: int = 8) -> tuple[ExecutiveCore, SentTimeline]:
    """Build an executive on a task, fed 1 s of healthy records.

    Navigation's come every 50 ms, the others every 10 ms, and every one is taken as soon as it
    is sent.
    """
    ex = ExecutiveCore(ExecutiveParams(status_timeout=0.15, stale_confirm=stale_confirm))
    t = SentTimeline()
    ex.on_record('comms_status', parse_task('stop at 2 first').record() | {'task_id': 1}, 0.0)
    for k in range(100):
        t.clock(k * 10 * MS, k * 0.01)
        for sub, fields in status_records(k * 0.01).items():
            if sub != 'navigation' or k % 5 == 0:
                ex.on_record(f'{sub}_status', fields, k * 0.01,
                             t.sim_at(k * 10 * MS) if sent else None)
        if k % 5 == 0:
            ex.tick(k * 0.01)
    assert ex.mode == 'running'
    return ex, t


def starved(age: str) -> ExecutiveCore:
    """Starve the executive from 1.0 s to 1.3 s of sim time while the sub-systems go on.

    Meanwhile 30 clock samples and 30 records of traction, route and load queue up, and 6 of
    navigation's (every 50 ms). Waking, it takes one record per topic per turn (rclpy's
    executor), the clock's first and navigation's last; its ROS clock (keep-last 1) is at 1.3 s
    at once, the FIFO clock one sample per turn. Pure age (stale_confirm 0).

    age: `arrival` (1983), `sent` (SentTimeline.record + sent_later), or `eager` (the send
    time as first placed, never raised: navigation's queue empties long before the clock's).
    """
    ex, t = cruising(age != 'arrival', stale_confirm=0)
    order = ('clock', 'traction', 'route', 'load', 'comms', 'navigation')
    queues: dict[str, list[int]] = {name: [] for name in order}
    for k in range(100, 130):
        for name in order:
            if name != 'navigation' or k % 5 == 0:
                queues[name].append(k * 10 * MS)
    ros_now = 1.30
    records = status_records(ros_now)
    while any(queues.values()) and ex.mode == 'running':
        for name in order:
            if not queues[name]:
                continue
            sent_ns = queues[name].pop(0)
            if name == 'clock':
                for record, sent in t.clock(sent_ns, sent_ns * 1e-9):
                    if age == 'sent':
                        ex.sent_later(record, sent)
            elif age == 'arrival':
                ex.on_record(f'{name}_status', records[name], ros_now)
            else:
                ex.on_record(f'{name}_status', records[name], t.now(),
                             t.record(f'{name}_status', sent_ns))
    return ex


def test_sent_ages_blame_nobody_when_the_executive_was_starved():
    assert starved('sent').mode == 'running'
    for age in ('arrival', 'eager'):
        blamed = starved(age)
        assert blamed.mode == 'failed' and blamed.fault == ('stale_status', 'navigation'), age


def test_a_silent_sub_system_is_still_stale_by_its_last_send():
    ex, t = cruising(sent=True)  # navigation dies after its record sent at 0.95 s
    k = 100
    while ex.mode == 'running':
        t.clock(k * 10 * MS, k * 0.01)
        for sub, fields in status_records(k * 0.01).items():
            if sub != 'navigation':
                ex.on_record(f'{sub}_status', fields, k * 0.01, t.sim_at(k * 10 * MS))
        k += 1
    assert ex.fault == ('stale_status', 'navigation')
    assert 0.95 + 0.15 - 1e-9 <= t.now() <= 0.95 + 0.15 + 0.01  # the first record past it
