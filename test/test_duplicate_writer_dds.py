"""A second executive on a running truck's domain: a duplicate writer, named, and the truck stops.

The whole graph runs (one process per node, sim time, demo_1983; test/graph_probe.py) and the
truck cruises a task when a second `executive` process, started as the launcher starts the first
(same parameter files), joins the domain with the world paused. Both write traction_command,
comms_command and the executive's other records as node /executive. Expected, from the
duplicate rule (records.writer_check: a record from a followed-then-replaced endpoint of the
writer while another writes is two live writers):

- traction rejects both executives' commands as `duplicate_writer` and opens its trip relay,
  cause `duplicate_writer`: the drive goes off and the truck comes to rest;
- traction's /diagnostics inputs row is ERROR and names both endpoints: the two GIDs the graph
  itself lists for node /executive on traction/command (asked here, apart from the check);
- the task fails on comms/report naming the duplicate: `FAILED: duplicate writer (executive)`
  when communications sees both executives' comms_command first (it can relay neither), or
  `FAILED: duplicate writer (traction)`, the launched executive's word on traction's trip,
  when that reaches communications first; the launched executive's log says
  `FAILED duplicate_writer (traction)` either way.
"""

from __future__ import annotations

import subprocess
import threading

from graph_probe import GraphProbe
import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]

TASK = 'stop at 2 second'


def executive_endpoints(g: GraphProbe) -> list[str]:
    """Return node /executive's writers of traction/command (GIDs, hex) as the graph lists them."""
    return sorted(bytes(i.endpoint_gid).hex()
                  for i in g.node.get_publishers_info_by_topic('traction/command')
                  if i.node_name == 'executive' and i.node_namespace == '/')


def start_second(g: GraphProbe, name: str) -> tuple[subprocess.Popen, list[str]]:
    """Start another process of node `name`, as the launcher starts the graph's own."""
    spec = next(s for s in g.launch.specs() if s.name == name)
    proc = subprocess.Popen(g.launch.command(spec, label=f'{name}_second'), env=g.launch.env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    return proc, lines


@pytest.mark.timeout(420)
def test_a_second_executive_is_a_named_duplicate_and_the_truck_stops(tmp_path, fault_table):
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.ros_ports import parse_links

    g = GraphProbe(tmp_path / 'logs')
    second = None
    try:
        links: list[str] = []  # graph/links lines, as they come (agv_nodes/ros_ports.py)
        g.node.create_subscription(String, 'graph/links', lambda m: links.append(m.data),
                                   qos.LATCHED)
        g.start_task(TASK)  # the first executive's line has come long before this returns
        first_line = next(line for line in reversed(links) if parse_links(line)[0] == 'executive')
        assert parse_links(first_line)[1], first_line  # its inputs, all matched by now
        speed = g.speed
        assert len(executive_endpoints(g)) == 1

        def join() -> None:  # with the world paused: its sim time of joining is exact
            nonlocal second, lines
            before = len(links)
            second, lines = start_second(g, 'executive')
            g.spin_until(lambda: len(executive_endpoints(g)) == 2, 120,
                         'the second executive on the graph')
            # the second's own line (the first's links do not change): every input the first
            # has matched, as the launcher waits for before the world moves (one that resumed
            # short of a status would call it stale: a fault of its own, not the duplicate),
            # and its traction_command writer matched traction's reader, so its records reach
            # traction from the resume on
            inputs = parse_links(first_line)[1]

            def second_ready() -> bool:
                for line in links[before:]:
                    name, matched, outputs = parse_links(line)
                    if name == 'executive' and inputs <= matched \
                            and outputs.get('traction_command') == 1:
                        return True
                return False
            g.spin_until(second_ready, 120,
                         f"the second executive's inputs and traction_command matched: "
                         f"{links[before:]}")
        lines: list[str] = []
        joined = g.at_exact_time(join)
        endpoints = executive_endpoints(g)
        at_rest = g.stays_at_rest() - joined
        cut = g.drive_off_after(joined)
        assert cut is not None, g.events
        # whichever sees it first: communications (both executives' comms_command) or the
        # launched executive (traction's trip), whose word communications relays until then
        g.report_with(f"'{TASK}': FAILED: duplicate writer (", wall_limit=60)
        failed = [r for r in g.reports if 'FAILED' in r]
        assert failed[0].endswith(('duplicate writer (executive)',
                                   'duplicate writer (traction)')), failed
        g.spin_until(lambda: 'duplicate writer' in g.errors.get('traction/inputs', ''), 60,
                     f"traction's inputs row naming the duplicate; have {g.errors}")
        row = g.errors['traction/inputs']
        print(f'second executive at {joined:.3f} s sim, {speed:.2f} m/s: drive off {cut:.3f} '
              f's after, at rest {at_rest:.2f} s later; reports {g.reports}; traction/inputs: '
              f'{row}')
        assert 'duplicate_writer' in g.trips, g.trips
        assert all(gid in row for gid in endpoints) and '/executive' in row, (endpoints, row)
        assert 'trip relay open: duplicate_writer' in row, row
        g.spin_until(lambda: any('FAILED duplicate_writer (traction)' in line
                                 for line in g.launch.lines if line.startswith('executive:')),
                     30, "the launched executive's failure line")
        assert second.poll() is None, ''.join(lines[-20:])
        fault_table.add('a second executive process joins the domain while cruising',
                        'the drive off, at rest, trip duplicate_writer, "FAILED: duplicate '
                        'writer (executive or traction)", traction/inputs ERROR naming both '
                        'GIDs',
                        f'at {speed:.2f} m/s: drive off {cut:.3f} s (sim) after it joined, at '
                        f'rest {at_rest:.2f} s after; "{failed[0]}"; traction/inputs: '
                        f'"{row[:120]}..."')
    finally:
        if second is not None and second.poll() is None:
            second.terminate()
            try:
                second.wait(timeout=10)
            except subprocess.TimeoutExpired:
                second.kill()
        g.close()
