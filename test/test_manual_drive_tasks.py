"""Manual mode entered and left by task (Rajagopalan 1991, App. F.4), the whole camera truck.

Lock step on junction_1991 (communications, executive, route following and the world, seeded):
`manual for T s` drives from cmd_vel for T s of sim time and completes with the motors off;
`manual` lasts until an abort; a drive fault fails it naming the fault; the 1983 truck refuses
it. The task texts and their refusals are docs/tasks.md's.
"""

from __future__ import annotations

import pytest

from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.harness import Harness, submit, truck

pytestmark = pytest.mark.timeout(60)

TELEOP = 0.1  # s between Twists


def camera_truck() -> Harness:
    h = truck('junction_1991', seed=1)
    h.run(0.2)
    return h


def teleop(h: Harness, seconds: float, linear: float) -> list[str]:
    route = h.cores['route_following']
    verdicts = []
    for _ in range(round(seconds / TELEOP)):
        verdicts.append(route.on_twist((linear, 0.0, 0.0), (0.0, 0.0, 0.0), h.now))
        h.run(TELEOP)
    return verdicts


def test_manual_for_t_seconds_drives_then_completes_and_stops():
    h = camera_truck()
    st, comms = h.world.vehicle.state, h.cores['communications']
    submit(h, 'manual for 5 s')
    h.run(0.2)
    start = h.now
    verdicts = teleop(h, 3.0, 0.3)
    assert verdicts.count('taken') == 30 and st.speed == pytest.approx(0.3, abs=0.002)
    # the operator keeps the key down past the task's end: refused from then on, never acted on
    verdicts = teleop(h, 4.0, 0.3)
    assert comms.results[-1] == (1, 'completed', 'none')
    ended = [n.time for n in h.cores['executive'].notes.recent if 'completed' in n.text][-1]
    assert ended - (start - 0.2) == pytest.approx(5.0, abs=0.06)  # its step, 50 ms passes
    assert verdicts[-15:] == ['not_manual'] * 15 and st.speed == 0.0
    assert not h.world.vehicle.enable


def test_manual_lasts_until_an_abort():
    h = camera_truck()
    st, comms = h.world.vehicle.state, h.cores['communications']
    submit(h, 'manual')
    h.run(0.2)
    teleop(h, 20.0, 0.2)  # 4 m at 0.2 m/s: still in manual mode
    assert st.speed == pytest.approx(0.2, abs=0.002) and h.cores['executive'].mode == 'running'
    submit(h, 'abort')
    verdicts = teleop(h, 1.0, 0.2)
    assert 'not_manual' in verdicts and verdicts[-1] == 'not_manual'
    assert not h.world.vehicle.enable and comms.results[-1][1] == 'completed'
    assert h.run(1.0, until=lambda: st.speed == 0.0)


def test_a_drive_fault_in_manual_mode_fails_the_task_naming_it():
    h = camera_truck()
    st, comms = h.world.vehicle.state, h.cores['communications']
    submit(h, 'manual')
    h.run(0.2)
    teleop(h, 3.0, 0.3)
    h.world.p.concic2.estop = True
    verdicts = teleop(h, 2.0, 0.3)
    # refused by the fault, then (the task failed, route following idle) by the mode
    assert st.speed == 0.0 and set(verdicts[2:]) <= {'drive_fault', 'not_manual'}
    assert verdicts[-1] == 'not_manual'
    assert h.cores['executive'].report == {'state': 'failed', 'cause': 'drive_fault',
                                           'subsystem': 'route', 'detail': 'estop'}
    assert comms.notes.texts()[-1] == "task 1 'manual': FAILED: drive fault (route): estop"


def test_the_wire_truck_refuses_a_manual_task():
    h = truck('demo_1983', seed=1)
    h.run(0.2)
    submit(h, 'manual for 5 s')
    h.run(0.5)
    assert h.cores['executive'].report['state'] == 'rejected'
    assert h.cores['route_following'].mode != 'manual'


@pytest.mark.timeout(10)
@pytest.mark.parametrize('text, column, reason', [
    ('manual for 0', 12, 'seconds 0 outside 1..255'),
    ('manual for 256 s', 12, 'seconds 256 outside 1..255'),
    ('manual 5', 8, "unexpected '5' after a complete task"),
    ('calibrate left', 11, "unexpected 'left' after a complete task"),
])
def test_bad_manual_and_calibrate_tasks_are_refused_naming_the_column(text, column, reason):
    with pytest.raises(TaskError) as caught:
        parse_task(text)
    assert (caught.value.column, caught.value.reason) == (column, reason)


@pytest.mark.timeout(10)
def test_manual_and_calibrate_tasks_as_comms_status_carries_them():
    assert (parse_task('manual').op, parse_task('manual').dwell) == ('manual', 0)
    assert parse_task('manual for 30 s').record()['dwell'] == 30
    assert parse_task('calibrate').record()['then'] == 'stay'
    assert parse_task('calibrate rear').record()['then'] == 'reverse'
