"""/clock over DDS: one writer (the world), and a jump of its clock is a named fault.

A rogue /clock writer (the probe node, in the test process) sends a time 5 s in the past while the
truck cruises: every node rejects each of its samples (core_node.ClockTimers, WriterCheck),
counts them in its `<node>/clock` /diagnostics row naming the foreign writer, and its time never
moves back: the truck drives on. The genuine writer jumping (the world's `clock_offset`, changed
at run time with the world paused at an exact time) is the fault `clock jumped`: the task ends
`FAILED: clock jumped (world)`, the truck comes to rest, traction's trip says clock_jumped, the
/clock rows give the times from and to, and nothing is blamed on a silent node (stale status,
stale_command). The world steps /clock by clock_every / sample_rate (config/agv_demo.yaml), so
the jump's `from` is the last /clock at or before the pause and its `to` the next one plus the
offset.
"""

from __future__ import annotations

import re

from graph_probe import CRUISE, GraphProbe
import pytest

from agv_nodes.package_share import config_dir
from agv_nodes.settings import parameter_file_values, parameters
from agv_nodes.world.settings import WorldParams

pytestmark = [pytest.mark.dds, pytest.mark.slow]

ROGUE_SAMPLES = 150
CORE_NODES = ('executive', 'traction', 'navigation', 'route_following', 'position_sensor',
              'load_handling', 'communications')
_JUMP = re.compile(r'clock jumped (back|forward) from ([0-9.]+) s to ([0-9.]+) s')


def clock_step() -> float:
    """Return the world's /clock step as launched: clock_every / sample_rate."""
    _shared, own = parameter_file_values(config_dir() / 'agv_demo.yaml', 'world')
    rate = next(p.default for p in parameters(WorldParams) if p.name == 'sample_rate')
    return own['clock_every'] / own.get('sample_rate', rate)


class ClockRows:
    """Every node's latest `<node>/clock` /diagnostics row: (level, message, values)."""

    def __init__(self, g: GraphProbe) -> None:
        from diagnostic_msgs.msg import DiagnosticArray

        from agv_nodes import qos

        self.rows: dict[str, tuple[int, str, dict[str, str]]] = {}
        g.node.create_subscription(DiagnosticArray, '/diagnostics', self._take, qos.EVENTS)

    def _take(self, msg) -> None:
        for st in msg.status:
            if st.name.endswith('/clock'):
                level = st.level if isinstance(st.level, int) else int.from_bytes(st.level)
                self.rows[st.hardware_id] = (level, st.message,
                                             {kv.key: kv.value for kv in st.values})


@pytest.mark.timeout(300)
def test_a_foreign_clock_is_rejected_counted_named_and_never_moves_time(tmp_path):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    g = GraphProbe(tmp_path / 'logs')
    rows = ClockRows(g)
    try:
        g.start_task('stop at 2 second')
        # deep enough that no sample leaves the history before every reader has it
        rogue = g.node.create_publisher(Clock, '/clock', QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=ROGUE_SAMPLES,
            reliability=ReliabilityPolicy.RELIABLE))
        g.spin_until(lambda: rogue.get_subscription_count() >= len(CORE_NODES), 30,
                     'the rogue /clock to match every node')
        start, trips_before = g.time, len(g.trips)
        for _ in range(ROGUE_SAMPLES):
            past = max(g.time - 5.0, 0.001)
            sec, nanosec = divmod(round(past * 1e9), 1_000_000_000)
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = sec, nanosec
            rogue.publish(msg)
            g.executor.spin_once(timeout_sec=0.002)

        def all_counted() -> bool:
            return all(node in rows.rows and rows.rows[node][2]['rejected'] == str(ROGUE_SAMPLES)
                       for node in CORE_NODES)
        g.spin_until(all_counted, 60, f'every node to count {ROGUE_SAMPLES} foreign /clock '
                     f'samples; rows {rows.rows}')
        for node in CORE_NODES:
            level, message, values = rows.rows[node]
            assert level < 2, (node, message)  # a foreign writer is no fault of the clock
            assert values['rejects by reason'] == f'foreign_writer={ROGUE_SAMPLES}', values
            assert 'fault_probe' in values['last rejection'], values
            assert values['jumps'] == 'none', values
        warned = [rows.rows[n][1] for n in CORE_NODES]
        assert any('foreign writer' in m and 'fault_probe' in m for m in warned), warned
        # time never went back, and the truck drives on
        assert g.time > start and g.speed > CRUISE, (g.time, start, g.speed)
        g.spin_until(lambda: g.time > start + 1.0, 30, 'one more second of sim time')
        assert g.speed > CRUISE, g.speed
        assert len(g.trips) == trips_before and not any('FAILED' in r for r in g.reports), \
            (g.trips, g.reports)
        assert not any('clock' in m for m in g.errors.values()), g.errors
    finally:
        g.close()


@pytest.mark.timeout(300)
@pytest.mark.parametrize('offset', [-1.0, 5.0], ids=['back', 'forward'])
def test_the_world_clock_jumping_fails_the_task_as_clock_jumped(tmp_path, offset):
    g = GraphProbe(tmp_path / 'logs')
    rows = ClockRows(g)
    try:
        g.start_task('stop at 2 second')
        assert g.time > 1.5  # the jump back keeps /clock above 0 (the world not started)
        at = g.at_exact_time(lambda: g.set_world(clock_offset=offset))
        g.report_with('FAILED: clock jumped (world)')
        g.stays_at_rest()
        assert 'clock_jumped' in g.trips, g.trips
        g.spin_until(lambda: all(n in rows.rows for n in CORE_NODES), 30,
                     f"every node's /clock row; have {sorted(rows.rows)}")
        step = clock_step()
        for node in CORE_NODES:
            level, message, values = rows.rows[node]
            found = _JUMP.search(message)
            assert level == 2 and found, (node, message)
            assert found[1] == ('back' if offset < 0 else 'forward'), message
            before, after = float(found[2]), float(found[3])
            # the last /clock at or before the pause, and the next one plus the offset
            # (printed to the ms)
            assert at - step - 0.0005 <= before <= at + 0.0005, (at, message)
            assert at + offset - 0.0005 <= after <= at + step + offset + 0.0005, (at, message)
        stale = [r for r in g.reports if 'stale' in r]
        assert not stale, g.reports
        blamed = {k: m for k, m in g.errors.items() if 'stale' in m}
        assert not blamed, blamed
        assert 'clock jumped' in g.errors.get('executive', ''), g.errors
        assert 'clock_jumped' in g.errors.get('traction/inputs', ''), g.errors
    finally:
        g.close()
