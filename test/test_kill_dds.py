"""A node process killed or frozen while the truck is moving over DDS: the truck must stop.

Each case starts the whole graph (one process per node, config/graph.yaml), gives the executive
a task that drives along the wire, waits until the simulated truck is running at speed, then
SIGKILLs or SIGSTOPs one node process: no goodbye, no last record. Within 200 ms of simulated
time the drive must stop pushing the truck (the world's ground-truth `drive_off` event: chopper
off, contactor or trip relay open, or plug braking), the truck must come to rest and stay there,
`/diagnostics` must name the silent sub-system, and a frozen node that wakes up again (SIGCONT)
must not start the truck: only a new task may. What stops the truck differs:

- route_following / navigation: the executive sees the sub-system's status go stale and
  e-stops through traction (stale_status fault, reported as a failed task);
- position_sensor: navigation's ADC samples stop, it declares the sensor lost, speed 0;
- executive: traction's command goes stale and the trip latches (stale_command);
- traction: nothing computes again, so the world's trip-relay monostable drops out when the
  watchdog count stops changing (thesis appendix B.2.1) and the truck coasts to rest;
- load_handling / communications: nothing on the path to the drive, but the executive
  supervises every sub-system's status, names the silent one (stale_status) and e-stops
  through traction. communications is supervised because a silent sub-system is a fault the
  executive stops on (Baker 1983, 7.2: a failing sub-system made the others reset, which hid
  the fault), and without it no abort reaches the truck; a killed communications cannot carry
  the report itself, so /diagnostics names it.

Speed is measured from /world/pose (the world's ground truth), in simulated time
(test/graph_probe.py). The 200 ms budget sets the demo graph's watchdogs (config/agv_demo.yaml);
each case also bounds the time from the silent node's last record to the drive going off by the
timeout that guards it plus the passes and samples between, every term the declared value the
graph runs with (silence_bound): a watchdog slower than declared fails the case.
"""

from __future__ import annotations

import math
import signal

from graph_probe import GraphProbe
from node_processes import alive, wait_until_on_the_graph
import pytest

from agv_nodes.records import codec

pytestmark = [pytest.mark.dds, pytest.mark.slow]

DRIVE_OFF_WITHIN = 0.200  # simulated s from the kill to the drive no longer pushing
# The record whose last send starts each victim's chain to the drive: the one its watchdog ages.
WATCHED = {'executive': 'traction_command', 'traction': 'traction_drive',
           'position_sensor': 'position_sensor_status', 'route_following': 'route_status',
           'navigation': 'navigation_status', 'load_handling': 'load_status',
           'communications': 'comms_status'}


def silence_bound(g: GraphProbe, victim: str) -> tuple[float, float, str]:
    """Sim s from the victim's last record to the drive off: at least, at worst, how made.

    At least the timeout that watches it (no watchdog fires early), less, where the reader ages
    the record from its arrival on its own clock, the most that clock may trail the world's
    (max_lag and a step); at worst that timeout plus the passes and samples between.

    Every term is what the launched graph declares (GraphProbe.settings). Node time moves in
    /clock steps (clock_every / sample_rate), so a timer or an arrival is due at most a step
    late; a record reaches the world at most max_lag after its writer's time, and the world acts
    at its next sample.
    """
    from agv_nodes.executive.settings import ExecutiveParams
    from agv_nodes.navigation.settings import NavigationParams
    from agv_nodes.traction.settings import TractionParams
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    tr, ex = g.settings('traction', TractionParams), g.settings('executive', ExecutiveParams)
    nav, hw = g.settings('navigation', NavigationParams), g.settings('world', WorldParams)
    node = g.settings('world', WorldNodeSettings)
    step, sample = node.clock_every / hw.sample_rate, 1 / hw.sample_rate
    world = node.max_lag + sample
    trail = node.max_lag + step
    if victim == 'traction':  # the trip relay's monostable: retriggers stop coming
        return hw.drive_watchdog, hw.drive_watchdog + step + world, (
            f'drive_watchdog {hw.drive_watchdog:g} + step + max_lag + sample')
    if victim == 'executive':  # traction ages the command from its arrival, on its clock
        worst = tr.command_timeout + step + tr.loop_period + step + world
        return tr.command_timeout - trail, worst, (
            f'command_timeout {tr.command_timeout:g} + step + loop_period + step + max_lag '
            '+ sample')
    # the executive supervises the status (aged from its send), its e-stop cuts the armature
    # the moment it reaches traction
    stale = stale_after(g, victim)
    supervised = stale + ex.supervision_period + step + step + world
    if victim == 'position_sensor':  # navigation's sensor watchdog, then its status
        worst = nav.sensor_timeout + nav.period + step + step + supervised - stale
        return nav.sensor_timeout - trail, worst, (
            f'sensor_timeout {nav.sensor_timeout:g} + period + step + step + '
            'supervision_period + step + step + max_lag + sample')
    return ex.status_timeout, supervised, (
        f'stale after {stale:.4f} (status_timeout {ex.status_timeout:g}, or stale_confirm '
        'records of the others and a pacing allowance) + supervision_period + step + step + '
        'max_lag + sample')


def estop_bound(g: GraphProbe, victim: str = 'navigation') -> tuple[float, float]:
    """Sim s from a silent sub-system's last status to the executive's e-stop record: (>, <=).

    The executive ages a status from its send exactly as the probe does (the same /clock
    samples, agv_nodes/sent_time.py), and checks every supervision_period on the clock's steps.
    It calls the status stale once it is older than status_timeout and stale_confirm records of
    the others have arrived since (stale_after).
    """
    from agv_nodes.executive.settings import ExecutiveParams
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    ex = g.settings('executive', ExecutiveParams)
    step = g.settings('world', WorldNodeSettings).clock_every / g.settings(
        'world', WorldParams).sample_rate
    return ex.status_timeout, stale_after(g, victim) + ex.supervision_period + step


def stale_after(g: GraphProbe, victim: str) -> float:
    """Sim s from `victim`'s last status until the executive may call it stale, at worst.

    The later of status_timeout and the arrival of stale_confirm records from the other
    sub-systems: they report on one grid (each its record table period), so those records are
    sent within ceil(stale_confirm / others) periods, and the last of them reaches the executive
    up to one pacing allowance late (max_lag + the progress period + a clock step: a writer may
    trail the world, and so the executive, by that much; agv_nodes/world/pacing.py).
    """
    from agv_nodes.executive.faults import SUBSYSTEM_OF
    from agv_nodes.executive.settings import ExecutiveParams
    from agv_nodes.world.pacing import GraphPacer
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    ex, node = g.settings('executive', ExecutiveParams), g.settings('world', WorldNodeSettings)
    step = node.clock_every / g.settings('world', WorldParams).sample_rate
    table = codec()
    others = [table[r].period_ms / 1000 for r in SUBSYSTEM_OF if r != WATCHED.get(victim)]
    confirm = math.ceil(ex.stale_confirm / len(others)) * max(others)
    allowance = GraphPacer(node.max_lag, (), clock_step=step).allowance
    return max(ex.status_timeout, confirm + allowance)

CASES = [  # victim, at rest within (sim s), report on comms/report, /diagnostics row, words
    ('route_following', 3.0, 'FAILED: stale status (route)', 'route', 'old'),
    ('navigation', 3.0, 'FAILED: stale status (navigation)', 'navigation', 'old'),
    ('position_sensor', 3.0, 'FAILED: sensor lost (navigation)', 'navigation',
     'marker sensor lost'),
    # nobody is left to report; traction's own /diagnostics row names the silent executive
    ('executive', 3.0, None, 'traction/inputs', 'stale_command (the executive is silent)'),
    ('traction', 5.0, 'FAILED: stale status (traction)', 'traction', 'old'),
    ('load_handling', 3.0, 'FAILED: stale status (load)', 'executive', 'stale status (load)'),
    # a woken communications reports it late; a killed one cannot
    ('communications', 3.0, 'FAILED: stale status (communications)', 'executive',
     'stale status (communications)'),
]


@pytest.mark.timeout(180)  # ~25 s alone
@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGSTOP], ids=['kill', 'stop'])
@pytest.mark.parametrize('victim, stop_within, report, diag_row, diag_words', CASES,
                         ids=[c[0] for c in CASES])
def test_silent_node_ends_in_a_stop(tmp_path, victim, stop_within, report, diag_row,
                                    diag_words, sig, fault_table):
    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add(victim)
    proc = g.launch.procs
    sent = g.watch_sent(WATCHED[victim])
    commands = sent if victim == 'executive' else g.watch_sent('traction_command')
    try:
        least, bound, terms = silence_bound(g, victim)
        g.start_task('stop at 2 second')
        speed = g.speed
        # The kill happens with the world paused, so its sim time is exact.
        killed_at = g.at_exact_time(lambda: proc[victim].send_signal(sig))
        at_rest = g.stays_at_rest() - killed_at
        last = g.last_sent_before(sent, killed_at)
        cut = g.drive_off_after(killed_at)
        print(f'{victim} {sig.name} at {killed_at:.3f} s sim, {speed:.2f} m/s, its last '
              f'{WATCHED[victim]} sent at {last:.4f} s: drive off {cut} s after the kill, at rest '
              f'{at_rest:.2f} s later; bound {bound * 1000:.1f} ms ({terms}); reports '
              f'{g.reports}; diagnostics errors {g.errors}')
        # world_event stamps are whole ms: the bounds are compared in them, rounded up. The
        # trip relay's own 200 ms (thesis B.2.1) counts from the last retrigger, not the kill.
        # The probe sees which record was sent last, not which one the watching node took:
        # one sent as the signal came may reach the probe and never the node (measured: a
        # navigation_status 50 ms later than the executive's last), and one the node took may
        # be missed by a loaded probe (a drive off 195 ms after the route_status the probe saw
        # last, 133 ms after the kill). So over DDS the tied bounds allow one period of the
        # watched record either way, and the hard bound after the kill stays the fault budget;
        # each timeout is held to one period of its value in lock step (test/test_timeouts.py).
        budget = None if victim == 'traction' else DRIVE_OFF_WITHIN
        period = codec()[WATCHED[victim]].period_ms / 1000
        limit = min(budget or 1.0, bound + period + last - killed_at)
        cut_ms = g.drive_off_ms(killed_at, math.ceil(limit * 1000) / 1000)
        since_last = cut_ms / 1000 + killed_at - last
        assert since_last > least - period - 0.0005, (
            f'drive off {since_last * 1000:.1f} ms after the last {WATCHED[victim]}: its '
            f'watchdog fired before its {least * 1000:.0f} ms')
        assert at_rest <= stop_within, f'{victim} {sig.name}: at rest only {at_rest:.2f} s after'
        trip = seen = ''  # the named trip or e-stop: as expected, as seen
        if victim == 'executive':
            assert g.trips and g.trips[-1] == 'stale_command', g.trips
            trip = seen = 'trip stale_command, '
        elif victim != 'traction':  # the executive's e-stop (byte 2 = 00H) cut the drive
            estop = [t for t, c in commands if t >= killed_at and not c['manual']
                     and c['demand'] == 0]
            assert estop and estop[0] <= killed_at + cut_ms / 1000, (estop, cut_ms)
            trip = seen = 'the executive e-stops (00H), '
            if victim != 'position_sensor':  # its own status went stale
                after, within = estop_bound(g, victim)  # one period either way, as above
                assert after - period < estop[0] - last <= within + period + 1e-6, (
                    estop[0] - last, within)
                trip = (f'the executive e-stops (00H) {(after - period) * 1000:.0f} < t <= '
                        f'{(within + period) * 1000:.1f} ms after its last {WATCHED[victim]} '
                        'seen (stale_after + supervision_period + step, one period of it '
                        'either way), ')
                seen = f'e-stop {(estop[0] - last) * 1000:.1f} ms after its last, '
        g.spin_until(lambda: diag_words in g.errors.get(diag_row, ''), 30,
                     f'/diagnostics naming {diag_row} ({diag_words!r}); have {g.errors}')
        if sig == signal.SIGSTOP:  # wakes up: its stale state must not move the truck
            proc[victim].send_signal(signal.SIGCONT)
        if victim == 'communications' and sig == signal.SIGKILL:
            report = None  # a killed communications cannot carry its own report
        if report:
            g.report_with(report)
        if sig == signal.SIGSTOP:
            g.stays_at_rest(what='the truck to stay stopped after SIGCONT')
            assert proc[victim].poll() is None, f'{victim} died after SIGCONT'
            # its own stall is not a lost world clock (agv_nodes/clock_watch.py)
            assert 'clock lost' not in g.errors.get(f'{victim}/inputs', ''), g.errors
        else:
            assert proc[victim].poll() == -signal.SIGKILL
        cause = f'"{report}"' if report else 'no report (communications is the one killed)'
        fault_table.add(f'{sig.name} {victim} while cruising',
                        (f'drive off <= {budget * 1000:.0f} ms (sim) after the {sig.name} and '
                         if budget else 'drive off ')
                        + f'{(least - period) * 1000:.0f} < t <= {(bound + period) * 1000:.1f} '
                        f'ms after its last {WATCHED[victim]} seen ({terms}, one period of it '
                        'either way), '
                        f'at rest <= {stop_within:g} s, {trip}'
                        f'{cause}, /diagnostics {diag_row} ERROR "{diag_words}"'
                        + ('; after SIGCONT still at rest, no "clock lost"'
                           if sig == signal.SIGSTOP else ''),
                        f'at {speed:.2f} m/s: drive off {cut_ms} ms after, '
                        f'{since_last * 1000:.1f} ms after its last {WATCHED[victim]}, at rest '
                        f'{at_rest:.2f} s after; {seen}{cause}; /diagnostics {diag_row}: '
                        f'"{g.errors[diag_row]}"')
    finally:
        if sig == signal.SIGSTOP and proc[victim].poll() is None:
            proc[victim].send_signal(signal.SIGCONT)  # so that it can shut down
        g.close()


AGV_LAUNCH = """
import os, sys, time
from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch
launch = Launch(Options(world='none', quiet=True, domain_id=int(os.environ['ROS_DOMAIN_ID']),
                        namespace='/killed_launcher'))
launch.start()
print(' '.join(str(p.pid) for p in launch.procs.values()), flush=True)
time.sleep(120)
"""
# what ros2 launch and ros2 run do with a node: a plain child process of theirs, no wrapper
PLAIN_PARENT = """
import subprocess, sys, time
from pathlib import Path
bin_dir = Path(sys.executable).parent
procs = [subprocess.Popen([str(bin_dir / node), '--ros-args', '-p', 'use_sim_time:=true',
                           '-r', '__ns:=/killed_parent'])
         for node in ('executive', 'traction', 'recorder')]
print(' '.join(str(p.pid) for p in procs), flush=True)
time.sleep(120)
"""


@pytest.mark.timeout(90)
@pytest.mark.parametrize('parent, nodes', [(AGV_LAUNCH, 7), (PLAIN_PARENT, 3)],
                         ids=['agv-launch', 'plain-parent'])
def test_a_sigkilled_launcher_takes_its_nodes_with_it(tmp_path, parent, nodes, fault_table):
    """No node is left running on the domain when whatever started it is SIGKILLed.

    The killed parent runs no clean-up: each node asked Linux for SIGTERM when its parent
    exits (agv_nodes/node_process.py die_with_parent; agv-launch's child wrapper asks the same).
    The plain parent starts nodes as ros2 launch and ros2 run do (ros2 launch itself is not on
    PyPI, so it is not run here).
    """
    import os
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, '-c', parent], stdout=subprocess.PIPE, text=True,
                            cwd=tmp_path)  # the recorder's bag goes there
    pids = [int(p) for p in proc.stdout.readline().split()]
    try:
        assert len(pids) == nodes  # agv-launch: world none, no recorder
        wait_until_on_the_graph(nodes, 30.0, '/killed_launcher' if parent is AGV_LAUNCH
                                else '/killed_parent')
        assert all(alive(p) for p in pids)
    except BaseException:  # not to the kill: leave nothing running on the domain
        for pid in [proc.pid, *pids]:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        raise
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    killed = time.monotonic()
    deadline = killed + 20.0
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)
    took = time.monotonic() - killed
    left = [p for p in pids if alive(p)]
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left, f'node processes outlived their launcher: {left}'
    which = 'agv-launch' if parent is AGV_LAUNCH else 'a plain parent (as ros2 launch/run)'
    fault_table.add(f'SIGKILL {which} with its nodes running',
                    'every node it started ends (SIGTERM from the kernel), none left on the '
                    'domain', f'all {nodes} gone {took:.1f} s after the kill')
