"""Faults over DDS in states beyond cruising: each must end with the truck at rest, cause named.

test_kill_dds.py silences each node while the truck cruises along the wire. Here the process
silenced is the one doing the work in the state the truck is in, SIGKILLed or SIGSTOPped (then
woken with SIGCONT) with the world paused so that its sim time is exact (test/graph_probe.py):

- positioning at a stop marker ('stop at 2 second', between W2.1 and W2.2): navigation drives
  the truck there through its link to traction (Position priority, Baker 1983, 6.3.1);
- a software-resident manoeuvre (demo_1983, from W1.1 by L1's SRM onto wire B): route following
  steers it open loop on odometry (Baker 1983, 7.2 task 7);
- the CONCIC-II's reverse leg (junction_1991, the rear camera leading): route following
  steers and drives both motors (Rajagopalan 1991, App. F.5); the world's 60 ms steering
  watchdog cuts them;
- a load transfer at W0 ('load at 0', the conveyor running, the truck at rest): the executive,
  which ordered it and holds the truck;
- two faults at once while cruising: the radio stop and a blinded marker sensor.

Each case bounds the drive going off by the watchdog that guards it, from the silenced node's
last record, with every term the value the launched graph declares (test_kill_dds.py,
silence_bound), and asserts the named cause: the report line and the /diagnostics row.
"""

from __future__ import annotations

import math
import signal

from graph_probe import AT_REST, GraphProbe
import pytest
from test_kill_dds import DRIVE_OFF_WITHIN, estop_bound, silence_bound

pytestmark = [pytest.mark.dds, pytest.mark.slow]

SIGNALS = pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGSTOP], ids=['kill', 'stop'])


def silence(g: GraphProbe, victim: str, sig: signal.Signals, sent: list[list],
            bounds: tuple[float, float, str] | None) -> dict:
    """Signal `victim` at an exact sim time; assert the drive goes off within `bounds`.

    `bounds` is (at least, at worst, how made) from the victim's last record in `sent` to the
    world's drive_off; None for a truck already at rest (then it must stay so). Returns what
    was measured, each value asserted.
    """
    speed = g.speed
    at = g.at_exact_time(lambda: g.launch.procs[victim].send_signal(sig))
    at_rest = g.stays_at_rest() - at
    last = g.last_sent_before(sent, at)
    out = {'at': at, 'speed': speed, 'at_rest': at_rest, 'last': last}
    if bounds is None:
        assert speed <= AT_REST and g.drive_off_after(at) is None, (speed, g.events[-5:])
        return out
    least, worst, terms = bounds
    cut = g.drive_off_after(at)
    assert cut is not None, f'no drive_off after {at:.3f} s (events {g.events[-5:]})'
    cut_ms = round(cut * 1000)  # world_event stamps are whole ms
    since_last = cut_ms / 1000 + at - last
    assert 0 < cut_ms <= round(DRIVE_OFF_WITHIN * 1000), f'drive off {cut_ms} ms after {at:.3f}'
    assert least - 0.0005 < since_last <= math.ceil(worst * 1000) / 1000 + 1e-9, (
        f'drive off {since_last * 1000:.1f} ms after the last record ({cut_ms} ms after the '
        f'{sig.name}): not in ({least * 1000:.0f}, {worst * 1000:.1f}] ({terms})')
    out.update(cut_ms=cut_ms, since_last=since_last)
    print(f'{victim} {sig.name} at {at:.3f} s, {speed:.2f} m/s: drive off {cut_ms} ms after, '
          f'{since_last * 1000:.1f} ms after its last record, at rest {at_rest:.2f} s later')
    return out


def estop_after(g: GraphProbe, commands: list[list], m: dict, victim: str) -> str:
    """Assert the executive's e-stop record came within estop_bound of the last status."""
    after, within = estop_bound(g, victim)
    estop = [t for t, c in commands if t >= m['at'] and not c['manual'] and c['demand'] == 0]
    assert estop and after < estop[0] - m['last'] <= within + 1e-6, (
        estop[:1], m, within, [(round(t - m['at'], 4), c) for t, c in commands[-12:]], g.reports)
    m['estop'] = estop[0] - m['last']
    return (f'the executive e-stops (00H) {after * 1000:.0f} < t <= {within * 1000:.1f} ms '
            'after the last status (status_timeout, or stale_confirm records of the others and a '
            'pacing allowance, + supervision_period + step); ')


def wake_and_name(g: GraphProbe, victim: str, sig: signal.Signals, report: str | None,
                  diag_row: str, diag_words: str) -> str:
    """Assert the cause named (report, /diagnostics), a woken victim moves nothing; say so."""
    g.spin_until(lambda: diag_words in g.errors.get(diag_row, ''), 30,
                 f'/diagnostics naming {diag_row} ({diag_words!r}); have {g.errors}')
    proc = g.launch.procs[victim]
    if sig == signal.SIGSTOP:
        proc.send_signal(signal.SIGCONT)
    if report:
        g.report_with(report)
    if sig == signal.SIGSTOP:
        woken = g.time
        g.stays_at_rest(what='the truck to stay stopped after SIGCONT')
        assert proc.poll() is None, f'{victim} died after SIGCONT'
        assert g.travelled_since(woken) < 0.005, g.travelled_since(woken)
    else:
        assert proc.poll() == -signal.SIGKILL
    line = next((r for r in g.reports if report and report in r), '')
    said = f'"{line.split(": ", 1)[1]}", ' if line else ''
    return f'{said}/diagnostics {diag_row}: "{g.errors[diag_row]}"'


def expected(bounds: tuple[float, float, str] | None, record: str, report: str | None,
             diag_row: str, diag_words: str, sig: signal.Signals) -> str:
    """Return the expected column: exactly what silence() and wake_and_name() assert."""
    cut = ('at rest before and after, no drive_off' if bounds is None else
           f'drive off <= {DRIVE_OFF_WITHIN * 1000:.0f} ms (sim) after the {sig.name}, '
           f'{bounds[0] * 1000:.0f} < t <= {bounds[1] * 1000:.1f} ms after its last {record} '
           f'({bounds[2]})')
    said = f'"{report}", ' if report else ''
    return (f'{cut}; at rest; {said}/diagnostics {diag_row} ERROR "{diag_words}"'
            + ('; woken (SIGCONT): still at rest' if sig == signal.SIGSTOP else ''))


def observed(m: dict, record: str, named: str) -> str:
    """Return the observed column: silence()'s measured values and the names asserted."""
    cut = ('at rest, no drive_off' if 'cut_ms' not in m else
           f'drive off {m["cut_ms"]} ms after, {m["since_last"] * 1000:.1f} ms after its last '
           f'{record}')
    if 'estop' in m:
        cut += f', e-stop {m["estop"] * 1000:.1f} ms after it'

    rest = ('at rest throughout' if 'cut_ms' not in m else
            f'at rest {m["at_rest"]:.2f} s after')
    return f'at {m["speed"]:.2f} m/s: {cut}, {rest}; {named}'


@pytest.mark.timeout(180)  # ~30 s alone
@SIGNALS
def test_navigation_silent_while_positioning_at_a_stop_marker(tmp_path, sig, fault_table):
    """Past W2.1 navigation drives on to W2.2 (Position priority), before its stop window.

    Once its link asks for the controlled stop (stop_in) traction brakes onto the marker by
    itself, so a signal then would test nothing: the truck stops anyway.
    """
    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add('navigation')
    links = g.watch_sent('traction_link')
    sent = g.watch_sent('navigation_status')
    commands = g.watch_sent('traction_command')
    try:
        bounds = silence_bound(g, 'navigation')
        g.start_task('stop at 2 second', cruise=None)

        def positioning() -> bool:
            link = links[-1][1] if links else {}
            return (not link.get('executive_priority', 1) and link.get('speed', 0) > 0
                    and not link.get('stop_in', 1) and g.speed > 0.3)
        g.spin_until(positioning, 120, 'navigation positioning the truck, W2.2 not yet in '
                     'its stop window')
        m = silence(g, 'navigation', sig, sent, bounds)
        link = [f for t, f in links if t <= m['at']][-1]  # the last it sent before the signal
        assert not link['executive_priority'] and link['speed'] and not link['stop_in'], link
        estop = estop_after(g, commands, m, 'navigation')
        named = wake_and_name(g, 'navigation', sig, 'FAILED: stale status (navigation)',
                              'executive', 'stale status (navigation)')
        fault_table.add(f'{sig.name} navigation while positioning at a stop marker (W2.2)',
                        'at the signal: traction_link with Position priority and a speed, no '
                        'controlled stop yet (stop_in 0), over 0.3 m/s; ' + estop
                        + expected(bounds, 'navigation_status',
                                   'FAILED: stale status (navigation)', 'executive',
                                   'stale status (navigation)', sig),
                        f'link speed {link["speed"]}, stop_in 0; ' + observed(
                            m, 'navigation_status', named))
    finally:
        _wake(g, 'navigation')
        g.close()


@pytest.mark.timeout(180)  # ~20 s alone
@SIGNALS
def test_route_following_silent_during_an_srm(tmp_path, sig, fault_table):
    """Set down at W1.1, the truck leaves by L1's SRM: route following steers it off the wire."""
    g = GraphProbe(tmp_path / 'logs', extra={'world': ['set_down:=[W1.1]']})
    g.expected_dead.add('route_following')
    sent = g.watch_sent('route_status')
    try:
        bounds = silence_bound(g, 'route_following')
        g.start_task('at 1 first', cruise=None)
        g.report_with("'at 1 first': completed")
        g.start_task('stop at 3 first', cruise=None)
        g.spin_until(lambda: sent and sent[-1][1]['state'] == 'srm_running' and g.speed > 0.2,
                     90, 'route following running the SRM at speed')
        m = silence(g, 'route_following', sig, sent, bounds)
        state = [f for t, f in sent if t <= m['at']][-1]['state']
        assert state == 'srm_running', state
        named = wake_and_name(g, 'route_following', sig, 'FAILED: stale status (route)',
                              'executive', 'stale status (route)')
        fault_table.add(f'{sig.name} route_following during an SRM (demo_1983, L1 onto wire B)',
                        'at the signal: route_status srm_running, over 0.2 m/s; '
                        + expected(bounds, 'route_status', 'FAILED: stale status (route)',
                                   'executive', 'stale status (route)', sig),
                        f'{state}; ' + observed(m, 'route_status', named))
    finally:
        _wake(g, 'route_following')
        g.close()


def camera_bounds(g: GraphProbe) -> tuple[float, float, str]:
    """From the last steering_command to the motors off: the safety supervisor's watchdog.

    The world times it from the record's arrival, in its own time: at least the watchdog after
    the send, at most a clock step and max_lag later, seen at the next sample.
    """
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    hw, node = g.settings('world', WorldParams), g.settings('world', WorldNodeSettings)
    step, sample = node.clock_every / hw.sample_rate, 1 / hw.sample_rate
    watchdog = hw.concic2.watchdog
    return watchdog, watchdog + step + node.max_lag + sample, (
        f'concic2.watchdog {watchdog:g} + step + max_lag + sample')


@pytest.mark.timeout(240)  # ~25 s alone
@SIGNALS
def test_route_following_silent_in_the_camera_trucks_reverse_leg(tmp_path, sig, fault_table):
    """junction_1991: 1.5 m along the tape, then back with the rear camera leading."""
    g = GraphProbe(tmp_path / 'logs', layout='junction_1991')
    g.expected_dead.add('route_following')
    sent = g.watch_sent('steering_command')
    legs = g.watch_sent('route_status')
    try:
        bounds = camera_bounds(g)
        g.start_task('tape for 1.5 m then reverse for 1.5 m', cruise=None)
        g.report_with('running (step 1)', wall_limit=120)

        def backing() -> bool:  # the truck's x (along the tape) falling at speed
            return len(g.path) > 2 and g.path[-1][1] < g.path[-2][1] and g.speed > 0.2
        g.spin_until(backing, 60, 'the reverse leg at speed')
        m = silence(g, 'route_following', sig, sent, bounds)
        leg = [f for t, f in legs if t <= m['at']][-1]
        x = [p[1] for p in g.path if p[0] <= m['at']]
        assert x[-1] < x[-2] and leg['leg'] == 2, (x[-3:], leg)
        named = wake_and_name(g, 'route_following', sig, 'FAILED: stale status (route)',
                              'executive', 'stale status (route)')
        fault_table.add(f'{sig.name} route_following of the camera truck in its reverse leg',
                        'at the signal: route_status leg 2, the truck backing over 0.2 m/s; '
                        + expected(bounds, 'steering_command', 'FAILED: stale status (route)',
                                   'executive', 'stale status (route)', sig),
                        f'leg {leg["leg"]}, backing; ' + observed(m, 'steering_command', named))
    finally:
        _wake(g, 'route_following')
        g.close()


@pytest.mark.timeout(240)  # ~25 s alone
@SIGNALS
def test_executive_silent_during_a_load_transfer(tmp_path, sig, fault_table):
    """W0 holds a load; the truck stops at W0.1 and its first conveyor runs: then the signal."""
    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add('executive')
    conveyor = g.watch_sent('conveyor_command')
    sent = g.watch_sent('traction_command')
    loads = g.watch_sent('load_status')
    try:
        g.start_task('load at 0', cruise=None)
        g.spin_until(lambda: conveyor and conveyor[-1][1]['first'] == 'load', 120,
                     'the conveyor to run')
        # 1 s into the 3.2 s transfer (transfer_length / conveyor_speed), counted from the
        # conveyor command's own sim time: the probe hears of it late on a loaded machine, and
        # counting from then could reach the transfer's end
        started = next(t for t, f in conveyor if f['first'] == 'load')
        g.spin_until(lambda: g.speed <= AT_REST, 10, 'the truck at rest')
        g.spin_until(lambda: g.time > started + 1.0, 30, '1 s of the transfer')
        m = silence(g, 'executive', sig, sent, None)
        running = [f for t, f in conveyor if t <= m['at']][-1]['first']
        assert running == 'load', running
        g.spin_until(lambda: 'stale_command' in g.trips, 30, 'traction to trip')
        # a killed executive reports nothing; a woken one fails the task (its cause: below)
        named = wake_and_name(g, 'executive', sig, 'FAILED: ' if sig == signal.SIGSTOP else None,
                              'traction/inputs', 'stale_command (the executive is silent)')
        # load handling finishes the job it was given on its own (the truck cannot move)
        g.spin_until(lambda: loads[-1][1]['state'] in ('done', 'failed'), 60,
                     'the transfer to end')
        transfer = loads[-1][1]
        ended = g.time
        g.spin_until(lambda: g.time > ended + 2.0, 60, '2 s after the transfer ended')
        moved = [round(t - m['at'], 2) for t, e in g.events if e['event'] == 'load_moved']
        print(f'executive {sig.name}: reports {g.reports}; errors {g.errors}; transfer '
              f'{transfer}; load_moved {moved} s after')
        assert g.travelled_since(m['at']) < 0.005, g.travelled_since(m['at'])
        fault_table.add(f'{sig.name} executive during a load transfer (W0.1, conveyor loading)',
                        'at the signal: conveyor_command first = load, the truck at rest; '
                        'traction trips stale_command; '
                        + expected(None, 'traction_command', None, 'traction/inputs',
                                   'stale_command (the executive is silent)', sig)
                        + ('; a "FAILED: " report once woken' if sig == signal.SIGSTOP else '')
                        + '; the transfer ends (load_status done or failed); moved < 5 mm',
                        f'{running}; trip stale_command; ' + observed(m, 'traction_command',
                                                                       named)
                        + f'; transfer {transfer["state"]}, load_moved {moved} s after; '
                        f'moved {g.travelled_since(m["at"]) * 1000:.1f} mm')
    finally:
        _wake(g, 'executive')
        g.close()


@pytest.mark.timeout(180)  # ~20 s alone
def test_radio_stop_and_a_blinded_sensor_at_once(tmp_path, fault_table):
    """Both at the same sim time while cruising: the contactor drops, both causes are named."""
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    g = GraphProbe(tmp_path / 'logs')
    try:
        # the world takes the input at its next sample, at most a clock step and max_lag on
        hw, node = g.settings('world', WorldParams), g.settings('world', WorldNodeSettings)
        within = math.ceil((node.clock_every + 1) / hw.sample_rate * 1000 + node.max_lag * 1000)
        g.start_task('stop at 2 second')
        speed = g.speed

        def both() -> None:
            g.radio_stop(True)
            g.set_world(**{'sensor.ambient': 400.0})
        at = g.at_exact_time(both)
        at_rest = g.stays_at_rest() - at
        cut_ms = g.drive_off_ms(at, within / 1000)
        # The executive fails the task on whichever it hears first (the radio stop comes in
        # traction's 50 ms status, the lost sensor in navigation's at once); /diagnostics keeps
        # both named while they last.
        causes = ('FAILED: radio stop (traction)', 'FAILED: sensor lost (navigation)')
        g.spin_until(lambda: any(c in r for r in g.reports for c in causes), 30,
                     f'a report naming one of {causes}')
        named = next(c for r in g.reports for c in causes if c in r)
        rows = {'traction': 'radio stop', 'navigation': 'marker sensor lost'}
        g.spin_until(lambda: all(w in g.errors.get(r, '') for r, w in rows.items()), 30,
                     f'/diagnostics naming both {rows}; have {g.errors}')
        diag = {r: g.errors[r] for r in rows}
        g.radio_stop(False)
        g.set_world(**{'sensor.ambient': 0.0})
        cleared = g.time
        g.stays_at_rest(what='the truck to stay stopped once both cleared')
        assert g.travelled_since(cleared) < 0.005
        print(f'radio stop + blinded sensor at {at:.3f} s, {speed:.2f} m/s: drive off {cut_ms} '
              f'ms, at rest {at_rest:.2f} s later; reports {g.reports}; errors {g.errors}')
        fault_table.add('radio stop and marker sensor blinded at once while cruising',
                        f"drive off <= {within} ms (the world's next sample + step + max_lag), "
                        f'at rest, "{causes[0]}" or "{causes[1]}", /diagnostics ERROR rows '
                        'traction "radio stop" and navigation "marker sensor lost" both; both '
                        'cleared: still at rest',
                        f'at {speed:.2f} m/s: drive off {cut_ms} ms after, at rest '
                        f'{at_rest:.2f} s after; "{named}"; /diagnostics {diag}')
    finally:
        g.close()

def _wake(g: GraphProbe, victim: str) -> None:
    """SIGCONT a stopped victim so that it can shut down."""
    proc = g.launch.procs.get(victim)
    if proc is not None and proc.poll() is None:
        proc.send_signal(signal.SIGCONT)
