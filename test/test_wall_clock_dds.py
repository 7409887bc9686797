"""The graph on the wall clock (use_sim_time false: how it runs against hardware) over DDS.

No /clock: every node's timers run from start-up, the world steps at time_factor 1 on its own
clock. This test guards two requirements of that configuration:

- the world must move: a node that stopped announcing its links once its inputs had matched
  and its clock ran (true at once on the wall clock) would hide from the world the readers of
  its outputs that match later, so ros_ports.LinkAnnouncer slows down instead of stopping;
- Ctrl-C must end every node cleanly, with no FATAL callback errors or 'context is invalid'
  from nodes still publishing and no node process hung in Fast DDS at exit until SIGKILL:
  node_process.spin_main takes SIGINT between callbacks, shuts its executor down before the
  node's entities go, and bounds the teardown (test_node_parameters).
"""

from __future__ import annotations

from graph_probe import STOP_TOLERANCE_MM, GraphProbe
import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]


def test_wall_clock_graph_completes_a_task_and_stops_on_sigint(tmp_path):
    g = GraphProbe(tmp_path / 'logs', use_sim_time=False, time_factor=1.0)
    try:
        g.start_task('stop at 2 first', cruise=None)
        g.report_with("'stop at 2 first': completed", wall_limit=120)
        stops = [e for _t, e in g.events if e['event'] == 'stopped']
        assert stops and abs(stops[-1]['error']) <= STOP_TOLERANCE_MM, stops
    finally:
        g.close()
    # Every process ended on the launcher's SIGINT, with status 0 and nothing fatal said.
    assert set(g.launch.exits) == set(g.launch.procs), g.launch.exits
    failed = {name: code for name, code in g.launch.exits.items() if code != 0}
    assert not failed, (failed, '\n'.join(g.launch.lines[-40:]))
    assert not g.launch.escalated, g.launch.escalated  # none needed SIGTERM or SIGKILL
    said = '\n'.join(g.launch.lines)
    # A Fast DDS entity-deletion deadlock ends that node's process by itself after
    # node_process.TEARDOWN_LIMIT, status 0: said, not failed on.
    print('\n'.join(line for line in g.launch.lines if 'teardown still blocked' in line))
    for bad in ('FATAL', 'Traceback', 'context is invalid'):
        assert bad not in said, said[-3000:]
