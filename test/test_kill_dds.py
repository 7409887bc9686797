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
(test/graph_probe.py). The 200 ms budget sets the demo graph's watchdogs (config/agv_demo.yaml).
"""

from __future__ import annotations

import signal

from graph_probe import GraphProbe
from node_processes import alive, wait_until_on_the_graph
import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]

DRIVE_OFF_WITHIN = 0.200  # simulated s from the kill to the drive no longer pushing
# Traction itself silent: the world's trip relay drops 200 ms after the last retrigger it
# received (thesis B.2.1's monostable), seen at the next 340 Hz sample. A retrigger traction
# sent just before the kill can reach the world after it: the paced world runs at most
# max_lag (10 ms, config/agv_demo.yaml) ahead of a node's records, so it is stamped at most
# that late (on a loaded machine a little over 0.2 s). world_event stamps are whole
# milliseconds.
MAX_LAG = 0.010
RELAY_DROPS_WITHIN = 0.200 + MAX_LAG + 1 / 340 + 0.001

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


@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGSTOP], ids=['kill', 'stop'])
@pytest.mark.parametrize('victim, stop_within, report, diag_row, diag_words', CASES,
                         ids=[c[0] for c in CASES])
def test_silent_node_ends_in_a_stop(tmp_path, victim, stop_within, report, diag_row,
                                    diag_words, sig, fault_table):
    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add(victim)
    proc = g.launch.procs
    try:
        g.start_task('stop at 2 second')
        speed = g.speed
        # The kill happens with the world paused, so its sim time is exact.
        killed_at = g.at_exact_time(lambda: proc[victim].send_signal(sig))
        at_rest = g.stays_at_rest() - killed_at
        print(f'{victim} {sig.name} at {killed_at:.2f} s sim, {speed:.2f} m/s: drive off '
              f'{g.drive_off_after(killed_at)} s, at rest {at_rest:.2f} s later; reports '
              f'{g.reports}; diagnostics errors {g.errors}')
        limit = RELAY_DROPS_WITHIN if victim == 'traction' else DRIVE_OFF_WITHIN
        cut = g.drive_off_ms(killed_at, limit)
        assert at_rest <= stop_within, f'{victim} {sig.name}: at rest only {at_rest:.2f} s after'
        if victim == 'executive':
            assert g.trips and g.trips[-1] == 'stale_command', g.trips
        g.spin_until(lambda: diag_words in g.errors.get(diag_row, ''), 30,
                     f'/diagnostics naming {diag_row} ({diag_words!r}); have {g.errors}')
        if sig == signal.SIGSTOP:  # wakes up: its stale state must not move the truck
            proc[victim].send_signal(signal.SIGCONT)
        if victim == 'communications' and sig == signal.SIGKILL:
            report = None
        if report:
            g.report_with(report)
        if sig == signal.SIGSTOP:
            g.stays_at_rest(what='the truck to stay stopped after SIGCONT')
            assert proc[victim].poll() is None, f'{victim} died after SIGCONT'
            # its own stall is not a lost world clock (agv_nodes/clock_watch.py)
            assert 'clock lost' not in g.errors.get(f'{victim}/inputs', ''), g.errors
        else:
            assert proc[victim].poll() == -signal.SIGKILL
        fault_table.add(f'{sig.name} {victim} while cruising',
                        f'drive off <= {limit:.3f} s (sim), at rest, cause reported, '
                        f'{diag_row} ERROR in /diagnostics, no restart',
                        f'at {speed:.2f} m/s: drive off after {cut / 1000:.3f} s, at rest after '
                        f'{at_rest:.2f} s; {report or g.trips[-1:] or g.errors[diag_row]}')
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
