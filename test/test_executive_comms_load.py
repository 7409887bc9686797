"""Executive, communications and load handling: cores alone, and the whole truck in lock step."""

from __future__ import annotations

import pytest

from agv_nodes.communications.core import CommunicationsCore
from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.core import ExecutiveCore, itinerary
from agv_nodes.executive.diagnostics import ERROR, OK, WARN, HealthMonitor
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.harness import DEMO_PROGRAMME, submit, truck
from agv_nodes.load_handling.core import LoadHandlingCore
from agv_nodes.navigation.settings import NavigationParams
from agv_nodes.report import final_stops


# -- communications ------------------------------------------------------------------------
@pytest.mark.parametrize('text, op, fields', [
    ('load at 0 then continue', 'load', {'location': 0, 'then': 'continue'}),
    ('unload at 2 second', 'unload', {'location': 2, 'marker': 'second', 'conveyor': 'second'}),
    ('wait at 0 for 3 s then continue', 'wait', {'dwell': 3}),
    ('stop at 2 first', 'stop', {'marker': 'first', 'then': 'stay'}),
    ('stop at 2 first then second', 'stop', {'marker': 'first_then_second'}),
    ('srm at 1 angle -20', 'srm', {'srm_angle': -20, 'then': 'continue'}),
    ('leave wire at 3', 'srm', {'location': 3, 'srm_angle': 15}),
    ('load A at 1 and take to 3', 'transfer', {'location': 1, 'destination': 3}),
    ('ABORT', 'abort', {}),
])
def test_task_language(text, op, fields):
    task = parse_task(text)
    assert task.op == op
    record = task.record()
    for key, value in fields.items():
        assert record[key] == value


@pytest.mark.parametrize('text, column, words', [
    ('lod at 2', 1, "unknown task 'lod'"),
    ('load at 7', 9, 'no such location marker'),
    ('stop at', 8, 'expected location'),
    ('stop at 2 sideways', 11, "unexpected 'sideways'"),
    ('wait at 1 for -3', 15, 'outside 0..255'),
    ('load A at 1 and take to 1', 25, 'destination equals the source'),
    ('load A at 1 and bring to 3', 17, "expected 'take'"),
    ('unload at 2 first then second', 24, 'is a stop task'),
    ('   ', 4, 'empty task'),
])
def test_bad_tasks_name_the_column_and_reason(text, column, words):
    with pytest.raises(TaskError) as info:
        parse_task(text)
    assert info.value.column == column and words in str(info.value)


def test_bad_task_changes_nothing():
    comms = CommunicationsCore()
    comms.on_task('stop at 2 first', 0.0)
    before = comms.tick(0.1)
    comms.on_task('stop at 9 first', 0.2)
    assert comms.tick(0.3) == before and len(comms.queue) == 1
    assert 'rejected' in comms.notes.texts()[-1] and 'column 9' in comms.notes.texts()[-1]


def test_status_query_is_answered_and_changes_nothing():
    comms = CommunicationsCore()
    assert comms.on_task('status', 0.0) is None
    assert comms.notes.texts()[-1] == 'comms: status: 0 in queue'
    comms.on_task('stop at 2 first', 0.1)
    before = comms.tick(0.2)
    assert comms.on_task('Status', 0.3) is None
    assert comms.notes.texts()[-1] == "comms: status: 1 in queue; head: task 1 'stop at 2 first'"
    assert comms.tick(0.4) == before and len(comms.queue) == 1
    comms.on_task('load at 0', 0.5)
    assert comms.queue[-1].task_id == 2  # a query takes no task number
    with pytest.raises(TaskError):
        parse_task('status now')


def test_comms_queue_relays_in_order_and_reports():
    comms = CommunicationsCore()
    comms.on_task('stop at 2 first', 0.0)
    comms.on_task('load at 0', 0.0)
    assert comms.tick(0.1)['comms_status']['task_id'] == 1
    base = {'step': 0, 'cause': 'none', 'subsystem': 'none', 'location': 2}
    comms.on_record('comms_command', {**base, 'task_id': 1, 'state': 'running'}, 1.0)
    out = comms.on_record('comms_command', {**base, 'task_id': 1, 'state': 'completed'}, 2.0)
    assert out['comms_status']['task_id'] == 2 and out['comms_status']['op'] == 'load'
    comms.on_record('comms_command', {**base, 'task_id': 2, 'state': 'failed',
                                      'cause': 'lost_wire', 'subsystem': 'route'}, 3.0)
    assert comms.results == [(1, 'completed', 'none'), (2, 'failed', 'lost_wire')]
    assert 'FAILED: lost wire (route)' in comms.notes.texts()[-1]


# -- executive -------------------------------------------------------------------------------
def test_itineraries_follow_fig_3_1():
    transfer = parse_task('load A at 1 and take to 3').record()
    assert [s.kind for s in itinerary(transfer)] == ['goto', 'load', 'goto', 'unload']
    six = parse_task('stop at 2 first then second').record()
    assert [(s.kind, s.location, s.edge) for s in itinerary(six)] == [
        ('goto', 2, 0), ('next_marker', 2, 1)]
    assert [s.kind for s in itinerary(parse_task('wait at 0 for 3 then continue').record())] \
        == ['goto', 'wait', 'continue']


def status_records(now_ok: float) -> dict:
    return {'navigation': {'at_location': 0, 'slow': 0, 'reverse': 0, 'lost': 0,
                           'last_marker': 0xFF, 'speed_request': 0x40, 'sensor_lost': 0,
                           'input_fault': 0, 'stop_view': 0},
            'traction': {'ref': 55, 'duty': 55, 'emergency_stop': 0, 'radio_stop': 0,
                         'tripped': 0, 'manual': 0, 'field_forward': 1, 'armature_on': 1,
                         'reversing': 0, 'source': 'executive', 'trip_cause': 'none',
                         'speed': 700},
            'route': {'state': 'following', 'lateral_error': 0, 'signal': 100, 'steering': 0,
                      'sign_left': 0, 'sign_right': 0, 'sign_straight': 0, 'manoeuvre': 0},
            'load': {'state': 'idle', 'cause': 'none', 'load_first': 0, 'load_second': 0,
                     'job': 0},
            # communications repeats the head of its queue (supervised like the others)
            'comms': parse_task('stop at 2 first').record() | {'task_id': 1}}


def running_executive() -> ExecutiveCore:
    ex = ExecutiveCore(ExecutiveParams())
    t = 0.0
    for sub, fields in status_records(t).items():
        ex.on_record(f'{sub}_status', fields, t)
    ex.on_record('comms_status', parse_task('stop at 2 first').record() | {'task_id': 1}, t)
    for k in range(10):
        t = k * 0.05
        for sub, fields in status_records(t).items():
            ex.on_record(f'{sub}_status', fields, t)
        out = ex.tick(t)
    assert ex.mode == 'running' and out['traction_command']['demand'] == 55
    return ex


@pytest.mark.parametrize('sub, change, cause', [
    ('route', {'state': 'lost'}, 'lost_wire'),
    ('navigation', {'sensor_lost': 1, 'lost': 1}, 'sensor_lost'),
    ('traction', {'tripped': 1, 'trip_cause': 'stale_command'}, 'tripped'),
    ('traction', {'radio_stop': 1}, 'radio_stop'),
])
def test_faults_give_an_emergency_stop_and_a_named_failure(sub, change, cause, fault_table):
    ex = running_executive()
    for k in range(10, 30):  # healthy records until past the start-up grace for traction's trip
        for name, fields in status_records(k * 0.05).items():
            ex.on_record(f'{name}_status', fields, k * 0.05)
        ex.tick(k * 0.05)
    t = 1.5
    records = status_records(t)
    records[sub] = {**records[sub], **change}
    for name, fields in records.items():
        ex.on_record(f'{name}_status', fields, t)
    out = ex.tick(t)
    assert out['traction_command']['demand'] == 0  # byte 2 = 00H: EMERGENCY STOP
    assert out['comms_command']['state'] == 'failed' and out['comms_command']['cause'] == cause
    assert out['navigation_command']['task_location'] == 0xFF
    for k in range(20):  # it stays stopped
        assert ex.tick(t + 0.05 * (k + 1))['traction_command']['demand'] == 0
    fault_table.add(f'executive: {sub} reports {change} (lock step)',
                    f'e-stop (byte 2 = 00H), task FAILED: {cause}, held',
                    'e-stop on the same tick, held for 1 s')


def test_stale_status_names_the_silent_subsystem():
    ex = running_executive()
    t = 0.5
    for k in range(10):  # traction falls silent; the others keep reporting
        t = 0.5 + k * 0.05
        for name, fields in status_records(t).items():
            if name != 'traction':
                ex.on_record(f'{name}_status', fields, t)
        out = ex.tick(t)
    assert ex.fault == ('stale_status', 'traction')
    assert out['comms_command']['subsystem'] == 'traction'
    rows = HealthMonitor().update(t, {}, {}, ex)
    assert rows[-1].level == ERROR and 'traction' in rows[-1].message


def test_a_silent_subsystem_is_noticed_between_ticks_when_others_report():
    ex = running_executive()  # last records and tick at 0.45 s; status_timeout 0.15 s
    out = None
    t = 0.45
    while out is None:  # route, navigation, load keep reporting every 10 ms; traction is silent
        t = round(t + 0.01, 3)
        for name, fields in status_records(t).items():
            if name != 'traction' and out is None:
                out = ex.on_record(f'{name}_status', fields, t)
    assert t == pytest.approx(0.45 + ExecutiveParams().status_timeout + 0.01)
    assert out['traction_command']['demand'] == 0 and ex.fault == ('stale_status', 'traction')


def test_a_silent_subsystem_on_the_common_grid_is_noticed_by_the_supervision_timer():
    """The others report together every 50 ms: the 10 ms supervision finds the stale status.

    Without it the check waits for the next 50 ms pass or arrival: status_timeout + 50 ms.
    """
    p = ExecutiveParams()
    ex = running_executive()  # last records and tick at 0.45 s; status_timeout 0.15 s
    out, t, k = None, 0.45, 0
    while ex.fault is None and k < 100:
        k += 1
        t = round(0.45 + k * p.supervision_period, 6)
        if k % 5 == 0:  # the common 50 ms grid: the others report, then the pass runs
            for name, fields in status_records(t).items():
                if name != 'traction':
                    ex.on_record(f'{name}_status', fields, t)
            ex.tick(t)
        out = ex.supervise(t)
    assert ex.fault == ('stale_status', 'traction')
    assert 0.45 + p.status_timeout < t <= 0.45 + p.status_timeout + p.supervision_period + 1e-9
    assert out['traction_command']['demand'] == 0
    # and the supervision alone never sends commands while all is well
    assert running_executive().supervise(0.46) is None


@pytest.mark.parametrize('sub', ['navigation', 'traction', 'route', 'load'])
def test_a_subsystem_restarted_during_a_task_fails_it_at_once(sub, fault_table):
    ex = running_executive()
    out = ex.on_writer_restart(f'{sub}_status', 0.47)
    assert out['traction_command']['demand'] == 0 and ex.fault == ('restarted', sub)
    assert out['comms_command']['state'] == 'failed'
    assert out['comms_command']['cause'] == 'restarted'
    idle = ExecutiveCore(ExecutiveParams())  # no task: a restart is no fault
    assert idle.on_writer_restart(f'{sub}_status', 0.0) is None and idle.fault is None


def test_a_respawned_navigation_stops_the_truck_in_lock_step(fault_table):
    """Navigation restarted while cruising: its new process knows nothing of the task."""
    h = truck('demo_1983', seed=1)
    submit(h, 'stop at 2 second')
    h.run(20.0, until=lambda: h.world.vehicle.state.speed > 0.5)
    at = h.now
    h.restart('navigation')
    h.run(1.0, until=lambda: any(e['event'] == 'drive_off' for e in h.events
                                 if e['time'] >= at))
    off = next(e['time'] for e in h.events if e['event'] == 'drive_off' and e['time'] >= at)
    assert h.cores['executive'].fault == ('restarted', 'navigation')
    assert off - at <= NavigationParams().status_period + 0.02, off - at
    h.run(3.0)
    assert h.world.vehicle.state.speed == 0.0
    fault_table.add('navigation restarted while cruising (lock step, new core and counters)',
                    'e-stop, task FAILED: restarted (navigation), truck at rest',
                    f'drive off {1000 * (off - at):.0f} ms after the restart')


def test_a_starved_executive_does_not_blame_a_record_still_in_its_queue():
    ex = running_executive()  # last records and tick at 0.45 s; status_timeout 0.15 s
    t = 0.45 + 0.25  # its clock jumps: it was starved, four records wait in its queues
    for name, fields in status_records(t).items():  # taken one topic after another
        assert ex.on_record(f'{name}_status', fields, t) is None
    assert ex.fault is None and ex.mode == 'running'
    assert ex.tick(t)['traction_command']['demand'] == 55


def test_traction_still_tripped_after_arming_is_armed_again_during_the_grace():
    ex = ExecutiveCore(ExecutiveParams())
    t = 0.0
    tripped = {'tripped': 1, 'trip_cause': 'startup'}
    ex.on_record('comms_status', parse_task('stop at 2 first').record() | {'task_id': 1}, t)
    sent = []
    for k in range(18):  # 0.9 s: traction never clears
        t = k * 0.05
        for name, fields in status_records(t).items():
            ex.on_record(f'{name}_status', fields | (tripped if name == 'traction' else {}), t)
        sent.append(ex.tick(t)['traction_command']['demand'])
    zeros = [k for k, d in enumerate(sent) if d == 0 and k and sent[k - 1] != 0]
    assert len(zeros) >= 2, sent  # 00H again after the first demand went unanswered
    assert ex.mode == 'running'


@pytest.mark.parametrize('cleared', [True, False])
def test_a_lost_said_before_the_task_holds_the_truck_until_the_route_speaks_again(cleared):
    # On the wall clock a starved pickup stream makes the route say LOST while the truck stands;
    # it clears at rest. A task starting on that old LOST holds the truck at 00H and fails
    # only if the route's next status still says LOST.
    ex = ExecutiveCore(ExecutiveParams())
    lost = status_records(0.0)
    lost['route'] = {**lost['route'], 'state': 'lost'}
    del lost['comms']  # its queue is empty until the task comes
    for name, fields in lost.items():
        ex.on_record(f'{name}_status', fields, 0.0)
    ex.on_record('comms_status', parse_task('stop at 2 first').record() | {'task_id': 1}, 0.02)
    assert ex.mode == 'running' and ex.fault is None
    assert ex.tick(0.02)['traction_command']['demand'] == 0  # held at 00H, not driven
    records = status_records(0.05)
    if not cleared:
        records['route'] = {**records['route'], 'state': 'lost'}
    for name, fields in records.items():
        ex.on_record(f'{name}_status', fields, 0.05)
    out = ex.tick(0.05)
    if cleared:
        assert ex.mode == 'running' and ex.fault is None
        demands = [out['traction_command']['demand']]
        for k in range(2, 6):
            for name, fields in status_records(k * 0.05).items():
                ex.on_record(f'{name}_status', fields, k * 0.05)
            demands.append(ex.tick(k * 0.05)['traction_command']['demand'])
        assert demands[-1] == 55, demands  # driven once the route said following
    else:
        assert ex.fault == ('lost_wire', 'route')
        assert out['traction_command']['demand'] == 0


@pytest.mark.parametrize('writers, named', [(['route_status'], 'route'),
                                             (['route_status', 'traction_status'], 'none')])
def test_reject_burst_is_a_fault_naming_the_writer(writers, named):
    ex = running_executive()
    limit = ex.p.reject_limit
    for k in range(limit):  # the budget itself is tolerated
        ex.on_reject(writers[k % len(writers)], 'bad_crc', 0.6 + k * 0.01)
    for name, fields in status_records(0.7).items():
        ex.on_record(f'{name}_status', fields, 0.7)
    ex.tick(0.7)
    assert ex.mode == 'running'
    ex.on_reject(writers[-1], 'bad_crc', 0.71)
    ex.tick(0.72)
    assert ex.fault == ('rejected_records', named)


def test_load_handling_checks_and_transfers():
    load = LoadHandlingCore()
    sensors = {'load_first': 0, 'load_second': 0, 'station_aligned': 1, 'station_load': 0,
               'station_full': 0, 'transfer': 0}
    load.on_record('conveyor_status', sensors, 0.0)
    out = load.on_record('load_command', {'action': 'load', 'conveyor': 'first', 'timeout': 5,
                                          'job': 1}, 0.0)
    assert out['load_status']['state'] == 'failed' and out['load_status']['cause'] == 'no_load'
    load.on_record('conveyor_status', {**sensors, 'station_load': 1}, 0.1)
    out = load.on_record('load_command', {'action': 'load', 'conveyor': 'first', 'timeout': 5,
                                          'job': 2}, 0.1)
    assert out['conveyor_command'] == {'first': 'load', 'second': 'off', 'station_request': 1}
    load.on_record('conveyor_status', {**sensors, 'station_load': 1, 'load_first': 1}, 2.0)
    out = load.tick(2.0)
    assert out['load_status']['state'] == 'done' and out['conveyor_command']['first'] == 'off'
    out = load.on_record('load_command', {'action': 'unload', 'conveyor': 'second',
                                          'timeout': 5, 'job': 3}, 3.0)
    assert out['load_status']['cause'] == 'no_load'  # nothing on the second conveyor
    load.on_record('conveyor_status', {**sensors, 'station_aligned': 0}, 4.0)
    load.on_record('load_command', {'action': 'load', 'conveyor': 'first', 'timeout': 5,
                                    'job': 4}, 4.0)
    assert load.tick(7.5)['load_status']['cause'] == 'truck_moving'  # never came to rest


# -- the whole truck -----------------------------------------------------------------------
def run_programme(tasks, limit: float = 900.0, **kw):
    h = truck('demo_1983', seed=kw.pop('seed', 1), **kw)
    for text in tasks:
        submit(h, text)
    comms, ex = h.cores['communications'], h.cores['executive']
    while h.now < limit and (comms.queue or ex.mode == 'running'):
        h.step()
    return h


@pytest.mark.slow
def test_demonstration_programme_completes_in_lock_step():
    """Thesis 7.2 tasks 1-7 and fig 3.1 on demo_1983, with the 1983 traction and friction stops.

    Every task, stop and load.
    """
    h = run_programme(DEMO_PROGRAMME, overrides={'traction': {'control': 'open_loop_1983'},
                                                 'navigation': {'stopping': 'friction_1983'}})
    comms = h.cores['communications']
    assert [r[1] for r in comms.results] == ['completed'] * len(DEMO_PROGRAMME)
    stops = [e for e in h.events if e['event'] == 'stopped']
    # Every requested stop, at the right stop marker, within the 1983 truck's +-4 cm about
    # its mean (the friction stop rolls ~3 cm past the centre, thesis 7.2).
    assert [e['marker'] for e in stops] == ['W0.1', 'W2.1', 'W0.1', 'W2.1', 'W1.1', 'W3.1',
                                            'W2.2', 'W2.1', 'W2.2']
    assert all(-10 <= e['error'] <= 70 for e in stops)
    moved = [e['marker'] for e in h.events if e['event'] == 'load_moved']
    assert moved == ['W0.1', 'W2.1', 'W1.1', 'W3.1']  # tasks 1, 2 and the fig 3.1 transfer
    world = h.world
    assert world.conveyors.station_loads == {'W0': 0, 'W1': 0, 'W2': 1, 'W3': 1}
    assert world.conveyors.loads == [False, False]
    reports = ' '.join(comms.notes.texts())
    assert reports.index("task 1 'load at 0") < reports.index("task 6 'load A at 1")
    assert h.cores['executive'].mode == 'idle' and world.vehicle.state.speed == 0.0


@pytest.mark.slow
def test_demonstration_programme_with_controlled_stops_ends_on_every_centre():
    """The defaults (closed-loop traction, controlled stops, thesis 8.5): the same programme.

    The truck comes to its final rest on every stop marker's centre. A controlled stop may rest
    more than once (an overshoot is backed out): the last counts.
    """
    h = run_programme(DEMO_PROGRAMME)
    assert [r[1] for r in h.cores['communications'].results] == ['completed'] * 8
    finals = final_stops(h.events)
    assert [e['marker'] for e in finals] == ['W0.1', 'W2.1', 'W0.1', 'W2.1', 'W1.1', 'W3.1',
                                             'W2.2', 'W2.1', 'W2.2']
    assert all(abs(e['error_mm']) <= 5 for e in finals), finals


def test_missing_stop_marker_stops_at_the_positioning_limit():
    h = truck('straight_track', seed=2)
    h.world.layout.markers = [m for m in h.world.layout.markers if m.station != 'S1']
    submit(h, 'stop at 1 first')
    ex = h.cores['executive']
    while h.now < 200 and ex.mode == 'running':
        h.step()
    assert ex.fault == ('route_limit', 'navigation')
    h.run(5.0)
    assert h.world.vehicle.state.speed == 0.0


def healthy_display() -> list:
    """Return the executive's display after 'stop at 0 first' and one more second at rest."""
    h = run_programme(['stop at 0 first'], limit=60)
    ex = h.cores['executive']
    member = next(m for m in h.members if m.core is ex)
    monitor = HealthMonitor()
    monitor.update(h.now, member.readers, member.writers, ex)
    h.run(1.0)
    return monitor.update(h.now, member.readers, member.writers, ex)


def test_diagnostics_rows_for_a_healthy_truck():
    rows = {r.name: r for r in healthy_display()}
    assert set(rows) == {'navigation', 'traction', 'route', 'load', 'communications',
                         'executive'}
    assert all(r.level == OK for r in rows.values()), {n: r.message for n, r in rows.items()}
    nav = rows['navigation'].values
    assert nav['in (hex)'].startswith('0B00') and len(nav['in (hex)']) == 32
    assert len(nav['out (hex)']) == 32 and 'task_location=0' in nav['out']
    assert float(rows['traction'].values['rate (Hz)']) == pytest.approx(20, abs=2)


def test_traction_start_up_trip_is_a_warning_and_a_fault_trip_an_error():
    """Before the first task traction's open relay is a WARN, a trip from a fault an ERROR.

    The relay is open by design then (power-on, awaiting 00H then non-zero): WARN, as in
    traction's own row, so agv-report lists no fault for a healthy start-up.
    """
    h = truck('demo_1983', seed=1)
    ex = h.cores['executive']
    member = next(m for m in h.members if m.core is ex)
    monitor = HealthMonitor()
    h.run(1.0)
    rows = {r.name: r for r in monitor.update(h.now, member.readers, member.writers, ex)}
    assert rows['traction'].level == WARN and rows['traction'].message == \
        'trip relay open: startup'
    assert all(r.level == OK for n, r in rows.items() if n != 'traction'), \
        {n: r.message for n, r in rows.items()}
    traction = member.readers['traction_status']
    traction.fields = dict(traction.fields, trip_cause='stale_command')
    rows = {r.name: r for r in monitor.update(h.now, member.readers, member.writers, ex)}
    assert rows['traction'].level == ERROR


def test_agv_diag_renders_the_32_byte_display():
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

    from agv_nodes.executive.diag_view import render

    msg = DiagnosticArray()
    for row in healthy_display():
        msg.status.append(DiagnosticStatus(level=bytes([row.level]), name=f'agv/{row.name}',
                                           message=row.message, hardware_id=row.name,
                                           values=[KeyValue(key=k, value=v)
                                                   for k, v in row.values.items()]))
    table = render(msg, detail='navigation', colour=False)
    lines = table.splitlines()
    assert lines[0].split()[:2] == ['sub-system', 'level']
    assert any(line.startswith('navigation') and ' OK ' in line for line in lines)
    assert any('in (hex)' in line and '0B00' in line for line in lines)  # the 16 bytes in
    assert any('out (hex)' in line for line in lines)


def test_final_stops_merge_the_rests_of_one_controlled_stop():
    def stopped(t: float, station: int, error: int, speed: int) -> dict:
        return {'event': 'stopped', 'time': t, 'marker_kind': 'stop', 'station': station,
                'identity': 1, 'error': error, 'speed': speed}
    load = {'event': 'load_moved', 'time': 0.0, 'marker_kind': 'stop', 'station': 2,
            'identity': 1, 'error': 0, 'speed': 0}
    events = [stopped(10.0, 2, 12, 700), stopped(11.5, 2, 0, 90),  # overshoot, backed up
              {**load, 'time': 14.0}, stopped(15.0, 2, 1, 40),  # a new stop after a load
              stopped(40.0, 2, 3, 700)]  # the same marker, much later
    finals = final_stops(events)
    assert [(s['time'], s['error_mm'], s['speed_mm_s'], s['rests']) for s in finals] == [
        (11.5, 0, 700, 2), (15.0, 1, 40, 1), (40.0, 3, 700, 1)]
