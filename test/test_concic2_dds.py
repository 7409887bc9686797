"""The 1991 camera truck over DDS: a scripted junction turn, a reverse leg, a kill, the demo.

The layout's vehicle picks the graph (config/graph.yaml `trucks`): on a tape layout agv-launch
starts the world, route following, executive and communications, each in its own process. A tape
task drives the CONCIC-II along junction_1991's tape, turns left at the R2 cross as scripted
(Rajagopalan 1991, App. F.6-F.7), follows the branch to its end, then reverses along it with the
rear camera leading; ground truth (/world/pose) shows where it went. Killing route following
while the truck drives must stop it: the world's 60 ms steering watchdog turns the motors off
(Rajagopalan 1991, 3.5), and the executive names the silent sub-system.
"""

from __future__ import annotations

import json
import signal

from graph_probe import GraphProbe
import pytest
from test_graph_dds import node_warnings, run_demo

pytestmark = [pytest.mark.dds, pytest.mark.slow]

CRUISE = 0.3  # m/s: the truck is under way (camera_speed 0.47)
LAYOUT = 'junction_1991'  # main tape along +x from the origin, R2 cross at x = 3, branches 3 m
CROSS_X = 3.0


@pytest.mark.timeout(240)
def test_junction_turn_then_reverse_leg_completes(tmp_path) -> None:
    g = GraphProbe(tmp_path / 'logs', layout=LAYOUT)
    try:
        assert sorted(s.name for s in g.launch.specs()) == [
            'communications', 'executive', 'route_following', 'world']
        g.start_task('tape junctions 1 left then reverse for 1.0 m', cruise=CRUISE)
        g.report_with('completed', wall_limit=180)
        assert not any('FAILED' in r for r in g.reports), g.reports
        # Forward: along the main tape, a quarter turn left over the cross, up the branch.
        far = max(g.path, key=lambda p: p[2])
        assert abs(far[1] - CROSS_X) < 0.03, f'left the cross at x = {far[1]:.3f}'
        assert far[2] > 2.0, f'the branch was followed only to y = {far[2]:.2f}'
        # Reverse: back down the branch by 1.0 m (the leg's length), still on the tape.
        end = g.path[-1]
        assert abs(end[1] - CROSS_X) < 0.02, f'reverse leg left the tape: x = {end[1]:.3f}'
        assert 0.9 < far[2] - end[2] < 1.15, f'reversed {far[2] - end[2]:.2f} m of 1.0'
    finally:
        g.close()


@pytest.mark.timeout(240)
def test_killing_route_following_stops_the_camera_truck(tmp_path, fault_table) -> None:
    g = GraphProbe(tmp_path / 'logs', layout=LAYOUT)
    g.expected_dead.add('route_following')
    try:
        g.start_task('tape for 5.0 m', cruise=CRUISE)
        killed_at = g.at_exact_time(
            lambda: g.launch.procs['route_following'].send_signal(signal.SIGKILL))
        rest = g.stays_at_rest() - killed_at
        cut = g.drive_off_ms(killed_at, 0.060 + 1 / 340 + 0.010 + 0.001)
        g.report_with('FAILED: stale status (route)')
        moved = g.travelled_since(killed_at)
        # motor-off coast from 0.47 m/s at 2.6 m/s^2: 42 mm, plus the 60 ms watchdog's travel
        assert moved < 0.47 * 0.075 + 0.47 ** 2 / (2 * 2.6) + 0.01, f'{moved:.3f} m'
        fault_table.add('SIGKILL route_following of the camera truck on a tape leg',
                        'motors off <= 0.074 s (sim: 60 ms watchdog, a world step, max_lag), at '
                        'rest, cause reported',
                        f'motors off after {cut} ms, at rest {rest:.2f} s after, '
                        f'{moved * 1000:.0f} mm travelled, FAILED: stale status (route)')
    finally:
        g.close()


@pytest.mark.timeout(600)
def test_quick_camera_demo_runs_a_scripted_turn_and_a_reverse_leg(tmp_path) -> None:
    """`agv-demo --truck concic2 --quick`, the CI variant: bag, report, every task completed."""
    res = run_demo(tmp_path, '--truck', 'concic2', '--quick', timeout=480)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:] + node_warnings(tmp_path)
    summary = json.loads((tmp_path / 'demo.json').read_text())
    assert summary['truck'] == 'concic2' and summary['processes'] == 5  # with the recorder
    assert [t['result'] for t in summary['tasks']] == ['completed'] * len(summary['tasks'])
    report = json.loads((tmp_path / 'report' / 'report.json').read_text())
    directions = [leg['direction'] for leg in report['legs']]
    assert 'forward' in directions and 'reverse' in directions, report['legs']
    assert report['signs'] and any(j['kind'] == 'turning' for j in report['junction_phases'])
    for png in ('camera_path.png', 'camera_timeline.png'):
        assert (tmp_path / 'report' / png).stat().st_size > 1000  # a real PNG, drawn
