"""The pause: `pause` brings the 1983 truck to rest with its task kept, `resume` drives on.

A modern addition (VDA 5050 2.1 startPause / stopPause, 6.8.2; Baker 1983 has no pause). The
commands and their record bit, then the whole truck in lock step (agv_nodes.harness on
demo_1983), judged by the world's ground truth: how far it rolls, that it stays at rest, and
that the task ends where it was asked to (agv_nodes.report.final_stops, the world's events).
The expected values come from the declared parameters (traction's ramp and coast deceleration,
the executive's rest_speed and rest_time) and from msg_schemas/, not from the pause's code.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.diagnostics import HealthMonitor
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.harness import Harness, submit, truck
from agv_nodes.records import codec
from agv_nodes.report import final_stops
from agv_nodes.traction.settings import TractionParams

pytestmark = pytest.mark.timeout(300)

TRACTION, EXECUTIVE = TractionParams(), ExecutiveParams()
STOP_TOLERANCE_MM = 5  # a controlled stop's final rest on the marker's centre (thesis 8.5)


# -- the commands and the record ----------------------------------------------------------------
def test_pause_and_resume_are_commands_carried_in_the_comms_status_record():
    comms = CommunicationsCore()
    comms.on_task('stop at 2 first', 0.0)
    out = comms.on_task('pause', 0.1)
    assert len(comms.queue) == 1  # never queued: the task at the head stays
    assert out['comms_status']['paused'] == 1 and out['comms_status']['op'] == 'stop'
    assert comms.notes.texts()[-1] == \
        'comms: pause: sent to the executive (1 in queue; task 1 kept)'
    schema = codec()['comms_status']
    raw = schema.encode({**out['comms_status']})
    assert raw[1] == (1 << 4) | 1  # byte 2 (raw[1]): op stop (1) in bits 0-3, paused bit 4
    assert schema.decode(raw)['paused'] == 1
    assert comms.tick(0.2)['comms_status']['paused'] == 1  # held until resume
    assert comms.on_task('RESUME', 0.3)['comms_status']['paused'] == 0
    assert comms.counts['pauses'] == 2 and comms.counts['queued'] == 1


def test_a_pause_is_never_refused_for_a_full_queue():
    comms = CommunicationsCore()
    for n in range(comms.p.max_queue + 1):
        comms.on_task(f'wait at 0 for {n} s', float(n))
    assert comms.counts['refused queue full'] == 1
    assert comms.on_task('pause', 100.0)['comms_status']['paused'] == 1
    assert comms.counts['pauses'] == 1 and comms.counts['refused queue full'] == 1


@pytest.mark.parametrize('text, column', [('pause now', 7), ('resume 2', 8)])
def test_a_pause_with_more_words_is_rejected_naming_the_column(text, column):
    with pytest.raises(TaskError) as info:
        parse_task(text)
    assert info.value.column == column
    comms = CommunicationsCore()
    assert comms.on_task(text, 0.0) is None and not comms.paused
    assert comms.counts['rejected'] == 1


def test_the_executives_word_on_the_pause_is_one_report_line_each_time_it_changes():
    comms = CommunicationsCore()
    word = {'task_id': 0, 'state': 'idle', 'step': 0, 'cause': 'none', 'subsystem': 'none',
            'location': 0xFF}
    for pause in ('none', 'stopping', 'stopping', 'paused', 'paused', 'none'):
        comms.on_record('comms_command', {**word, 'pause': pause}, 0.0)
    assert comms.notes.texts() == ['truck pausing: coming to rest, its task kept',
                                   'truck paused: at rest until resume',
                                   'truck resumed: it drives as its task asks']


# -- the whole truck ------------------------------------------------------------------------
def stop_bound(v0: float) -> float:
    """Return how far the truck may roll from `v0` m/s once paused, from declared parameters.

    The request waits at most one executive period and one traction pass; traction's demand
    ramp reaches max_decel after max_decel / max_jerk s, during which the truck is taken at v0;
    from there at least coast_decel slows it (traction's own figure for the truck coasting).
    """
    latency = EXECUTIVE.period + TRACTION.loop_period
    ramp = TRACTION.max_decel / TRACTION.max_jerk
    return v0 * (latency + ramp) + v0 * v0 / (2 * TRACTION.coast_decel)


class Watch:
    """The truck's ground truth and traction's demand, step by step."""

    def __init__(self, h: Harness) -> None:
        self.h = h
        self.vehicle = h.world.vehicle
        self.last = self.vehicle.sensor_point
        self.travelled = 0.0
        self.demands: list[int] = []
        self.speeds: list[float] = []

    def run(self, seconds: float, until: Any = None) -> bool:
        end = self.h.now + seconds
        while self.h.now < end:
            self.h.step()
            point = self.vehicle.sensor_point
            self.travelled += math.dist(point, self.last)
            self.last = point
            self.demands.append(self.h.cores['traction'].command['demand'])
            self.speeds.append(abs(self.vehicle.state.speed))
            if until is not None and until():
                return True
        return False

    def reset(self) -> None:
        self.travelled, self.demands, self.speeds = 0.0, [], []


def lines(h: Harness) -> list[str]:
    return h.cores['communications'].notes.texts()


def test_pause_while_cruising_stops_within_the_drives_distance_and_the_task_carries_on():
    h = truck('demo_1983', seed=1)
    ex, comms = h.cores['executive'], h.cores['communications']
    submit(h, 'stop at 2 first')
    watch = Watch(h)
    # at cruise: the demand ramp is over (0.67 m/s at 55 %)
    assert watch.run(20.0, until=lambda: h.now > 6.0 and ex.step.kind == 'goto')
    v0 = watch.vehicle.state.speed
    assert v0 > 0.6 and ex.phase == 'navigating'
    watch.reset()
    submit(h, 'pause')
    assert watch.run(10.0, until=lambda: watch.speeds[-1] == 0.0)
    rest = watch.travelled
    assert 0.0 < rest <= stop_bound(v0), (rest, stop_bound(v0))
    watch.reset()
    watch.run(15.0)  # the whole pause: not a millimetre, and never an emergency stop (00H)
    assert max(watch.speeds) == 0.0 and watch.travelled == 0.0
    assert 0 not in watch.demands and not h.cores['traction'].tripped
    assert ex.mode == 'running' and ex.step.kind == 'goto' and comms.results == []
    assert ex.pause == 'paused'
    assert lines(h)[-2:] == ['truck pausing: coming to rest, its task kept',
                             'truck paused: at rest until resume']
    submit(h, 'resume')
    assert watch.run(120.0, until=lambda: not comms.queue)
    assert comms.results == [(1, 'completed', 'none')]
    final = final_stops(h.events)[-1]
    assert final['marker'] == 'W2.1' and abs(final['error_mm']) <= STOP_TOLERANCE_MM, final
    assert 'truck resumed: it drives as its task asks' in lines(h)


def test_pause_while_positioning_on_the_stop_marker_does_not_miss_it():
    h = truck('demo_1983', seed=2)
    ex, comms = h.cores['executive'], h.cores['communications']
    submit(h, 'stop at 2 first')
    watch = Watch(h)
    assert watch.run(120.0, until=lambda: ex.phase == 'positioning')
    submit(h, 'pause')
    assert watch.run(10.0, until=lambda: ex.pause == 'paused')
    watch.reset()
    watch.run(5.0)
    assert watch.travelled == 0.0 and ex.mode == 'running' and comms.results == []
    submit(h, 'resume')
    assert watch.run(60.0, until=lambda: not comms.queue)
    assert comms.results == [(1, 'completed', 'none')]
    final = final_stops(h.events)[-1]
    assert final['marker'] == 'W2.1' and abs(final['error_mm']) <= STOP_TOLERANCE_MM, final


def test_pause_during_a_dwell_lets_it_run_out_and_holds_the_truck_until_resume():
    h = truck('demo_1983', seed=3)
    ex, comms = h.cores['executive'], h.cores['communications']
    submit(h, 'wait at 0 for 3 s then continue')
    watch = Watch(h)
    assert watch.run(120.0, until=lambda: ex.step is not None and ex.step.kind == 'wait')
    submit(h, 'pause')
    watch.reset()
    # the dwell goes on ("Actions can continue", 6.8.2) and ends; the task's next step would
    # drive on along the wire, and the pause holds it
    assert watch.run(20.0, until=lambda: bool(comms.results))
    watch.run(5.0)
    assert comms.results == [(1, 'completed', 'none')] and ex.mode == 'cruising'
    assert watch.travelled == 0.0 and max(watch.speeds) == 0.0
    submit(h, 'resume')
    assert watch.run(10.0, until=lambda: watch.vehicle.state.speed > 0.3)


def test_pause_while_loading_lets_the_load_finish_without_moving():
    h = truck('demo_1983', seed=4)
    ex, comms = h.cores['executive'], h.cores['communications']
    submit(h, 'load at 0 first')
    watch = Watch(h)
    assert watch.run(120.0, until=lambda: ex.step is not None and ex.step.kind == 'load')
    submit(h, 'pause')
    watch.reset()
    assert watch.run(30.0, until=lambda: bool(comms.results))
    assert comms.results == [(1, 'completed', 'none')]
    assert h.world.conveyors.loads == [True, False]
    watch.run(3.0)
    assert watch.travelled == 0.0 and max(watch.speeds) == 0.0
    submit(h, 'resume')
    watch.run(3.0)
    assert watch.travelled == 0.0  # the task is over: the truck stays put (then stay)


def test_pause_and_resume_with_no_task():
    h = truck('demo_1983', seed=5)
    ex = h.cores['executive']
    watch = Watch(h)
    watch.run(1.0)
    submit(h, 'pause')
    asked = h.now
    # at rest already: paused once rest_time has passed, within one executive period
    assert watch.run(2.0, until=lambda: ex.pause == 'paused')
    assert h.now - asked <= EXECUTIVE.rest_time + 2 * EXECUTIVE.period
    row = HealthMonitor._executive_row(ex)  # /diagnostics: the executive's row says it
    assert row.values['pause'] == 'paused' and row.message == 'idle, pause paused'
    submit(h, 'resume')
    assert watch.run(1.0, until=lambda: ex.pause == 'none')
    assert watch.travelled == 0.0 and ex.mode == 'idle'
    assert lines(h)[-5:] == [
        'comms: pause: sent to the executive (0 in queue)',
        'truck pausing: coming to rest, its task kept', 'truck paused: at rest until resume',
        'comms: resume: sent to the executive (0 in queue)',
        'truck resumed: it drives as its task asks']


def test_the_camera_truck_answers_that_it_cannot_pause():
    h = truck('tape_1991', seed=1)
    ex = h.cores['executive']
    h.run(0.5)
    submit(h, 'pause')
    h.run(1.0)
    assert ex.pause == 'unable' and not ex.pausing()
    assert lines(h)[-1] == 'truck cannot pause: its executive has no pause for this guidance'
