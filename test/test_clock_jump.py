"""The clock-jump rule (agv_nodes/clock_jump.py); what the executive and traction make of a jump.

The limit is the declared default of `clock_jump_limit` (agv_nodes/parameters.yaml), the world's
/clock step the one agv-launch runs it at (config/agv_demo.yaml's clock_every over the world's
sample_rate): neither comes from the rule. The lock-step truck then takes a jump as a node does
(core_node.CoreNode._jumped: each core's on_clock_jump) while it cruises; the same over DDS, with
the world's /clock really jumping, is test/test_clock_writer_dds.py.
"""

from __future__ import annotations

import pytest

from agv_nodes.clock_jump import ClockJumpRule, Jump
from agv_nodes.communications.report_line import progress_line, read_report
from agv_nodes.communications.task_language import parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.harness import submit, truck
from agv_nodes.package_share import config_dir
from agv_nodes.settings import NodeSettings, parameter_file_values, parameters
from agv_nodes.traction.core import TractionCore
from agv_nodes.world.settings import WorldNodeSettings, WorldParams

AT_REST = 0.005  # m/s (test/graph_probe.py)
LIMIT_S = next(p.default for p in parameters(NodeSettings) if p.name == 'clock_jump_limit')
LIMIT = round(LIMIT_S * 1e9)


def world_step_ns() -> int:
    """Return the world's /clock step as agv-launch runs it: clock_every / sample_rate."""
    _shared, own = parameter_file_values(config_dir() / 'agv_demo.yaml', 'world')
    defaults = {p.name: p.default for cls in (WorldNodeSettings, WorldParams)
                for p in parameters(cls)}
    every = own.get('clock_every', defaults['clock_every'])
    rate = own.get('sample_rate', defaults['sample_rate'])
    return round(every / rate * 1e9)


def test_the_limit_lies_between_the_world_step_and_the_shortest_watchdog():
    _shared, own = parameter_file_values(config_dir() / 'agv_demo.yaml', 'traction')
    assert world_step_ns() < LIMIT < round(own['command_timeout'] * 1e9)


def test_the_world_stepping_its_clock_is_no_jump():
    rule, step, t = ClockJumpRule(LIMIT_S), world_step_ns(), 9_000_000
    for seq in range(1, 2000):
        assert rule.take(t, seq) == t  # the node's time is the writer's
        assert rule.jump is None
        t += step
    assert rule.jumps == [] and rule.offset_ns == 0


def test_the_same_time_again_is_no_jump():  # the world's nudge to a lagging node
    rule = ClockJumpRule(LIMIT_S)
    rule.take(1_000_000_000, 1)
    assert rule.take(1_000_000_000, 2) == 1_000_000_000 and rule.jump is None


@pytest.mark.parametrize('sequenced', [True, False], ids=['sequence', 'no-sequence'])
def test_forward_past_the_limit_is_a_jump_and_the_node_time_runs_on(sequenced):
    rule = ClockJumpRule(LIMIT_S)
    seq = iter(range(1, 100)) if sequenced else iter([0] * 100)
    t0 = 2_000_000_000
    rule.take(t0, next(seq))
    assert rule.take(t0 + LIMIT, next(seq)) == t0 + LIMIT and rule.jump is None  # at the limit
    t1 = t0 + LIMIT
    assert rule.take(t1 + LIMIT + 1, next(seq)) == t1  # 1 ns past: the node's time stands
    assert rule.jump == Jump(t1, t1 + LIMIT + 1) and not rule.jump.back
    assert rule.take(t1 + LIMIT + 1 + 5_000_000, next(seq)) == t1 + 5_000_000  # then runs on
    assert rule.jump is None and len(rule.jumps) == 1


def test_back_is_a_jump_however_small():
    rule = ClockJumpRule(LIMIT_S)
    rule.take(7_000_000_000, 1)
    assert rule.take(6_999_999_999, 2) == 7_000_000_000
    assert rule.jump is not None and rule.jump.back
    assert rule.jump.text() == 'clock jumped back from 7.000 s to 7.000 s'
    rule.take(2_000_000_000, 3)  # 5 s back: timeouts neither fire nor wait 5 s
    assert rule.jump.text() == 'clock jumped back from 7.000 s to 2.000 s'
    assert rule.take(2_010_000_000, 4) == 7_010_000_000  # on from where it stood


def test_samples_this_reader_lost_are_no_jump():
    """A frozen reader's gap: the writer sent `lost + 1` samples; each stepped within the limit."""
    rule, step = ClockJumpRule(LIMIT_S), world_step_ns()
    rule.take(1_000_000_000, 10)
    lost = 300  # 2.6 s of samples gone from the writer's history
    assert rule.take(1_000_000_000 + (lost + 1) * step, 10 + lost + 1) == \
        1_000_000_000 + (lost + 1) * step
    assert rule.jump is None
    # but two samples sent may not carry more than two limits
    t = 1_000_000_000 + (lost + 1) * step
    rule.take(t + 2 * LIMIT + 1, 10 + lost + 3)
    assert rule.jump == Jump(t, t + 2 * LIMIT + 1)


def test_a_restarted_writer_counts_its_samples_afresh():
    rule = ClockJumpRule(LIMIT_S)
    rule.take(3_000_000_000, 5000)
    rule.restart()
    assert rule.take(3_000_000_000 + world_step_ns(), 1) == 3_000_000_000 + world_step_ns()
    assert rule.jump is None
    rule.take(0 + 1, 2)  # a world that starts again at 0 is a jump back
    assert rule.jump is not None and rule.jump.back


@pytest.mark.timeout(120)
def test_a_jump_while_cruising_fails_the_task_as_clock_jumped_and_stops_the_truck():
    h = truck()
    submit(h, 'stop at 2 second')
    assert h.run(30.0, until=lambda: h.world.pose()[3] > 0.6), 'the truck never cruised'
    jump = Jump(round(h.now * 1e9), round((h.now - 5.0) * 1e9))
    for m in h.members:  # as each node's /clock reader tells its core (core_node._jumped)
        handler = getattr(m.core, 'on_clock_jump', None)
        if handler is not None:
            h._publish(m, handler(jump.text(), h.now))
    h.run(5.0)
    comms, traction = h.cores['communications'], h.cores['traction']
    assert comms.results == [(1, 'failed', 'clock_jumped')]
    lines = [n.text for n in comms.notes.take()]
    failed = [line for line in lines if 'FAILED' in line]
    assert failed and 'FAILED: clock jumped (world)' in failed[-1], lines
    assert not any('stale' in line for line in lines), lines
    report = read_report(failed[-1])
    assert report.cause == 'clock jumped (world)'
    assert traction.tripped and traction.trip_cause == 'clock_jumped'
    assert traction.health() == (2, f'trip relay open: clock_jumped ({jump.text()})')
    assert abs(h.world.pose()[3]) < AT_REST
    assert h.cores['executive'].fault == ('clock_jumped', 'world')


def test_the_report_line_names_the_clock():
    line = progress_line(3, 'stop at 2 second', {'state': 'failed', 'step': 0,
                                                'cause': 'clock_jumped', 'subsystem': 'world',
                                                'location': 255})
    assert line == "task 3 'stop at 2 second': FAILED: clock jumped (world)"


def test_the_executive_alone_fails_the_task_and_stops_at_once():
    """Its own /clock reader's word suffices: the e-stop goes out with the failure."""
    ex = ExecutiveCore(ExecutiveParams())
    ex.on_record('comms_status', parse_task('stop at 2 first').record() | {'task_id': 1}, 0.0)
    assert ex.mode == 'running'
    out = ex.on_clock_jump('clock jumped back from 3.000 s to 2.000 s', 0.5)
    assert out['traction_command']['demand'] == 0  # 00H: the emergency stop (thesis 8.2)
    report = out['comms_command']
    assert (report['state'], report['cause'], report['subsystem']) == \
        ('failed', 'clock_jumped', 'world')
    assert ex.on_clock_jump('again', 0.6) is None  # no task running: nothing to stop


def test_traction_opens_its_relay_named_for_the_clock():
    traction = TractionCore()
    traction.tripped, traction.trip_cause = False, 'none'  # armed and running
    traction.on_clock_jump('clock jumped forward from 3.000 s to 8.000 s', 3.0)
    assert traction.tripped and traction.status()['trip_cause'] == 'clock_jumped'
    drive = traction.drive()  # the contactor open: no armature, no field
    assert (drive['contactor'], drive['armature_duty'], drive['field_duty']) == (0, 0, 0)
