"""A driver that is no ROS node, admitted by the identity it controls: its writer's GID.

test/plain_dds_peer.py writes adc_snapshot records on plain Cyclone DDS (no rclpy: the graph
names its writer `_CREATED_BY_BARE_DDS_APP_`, no ROS node) into a position_sensor node on Fast
DDS (rclpy's rmw), on the wall clock as on real boards. Named in the reader's record_writers by
its GID (`adc_snapshot=gid:<hex>`, the GID the peer prints and the graph lists for it), its
records are accepted and none rejected; without that entry every one is `foreign_writer` and
none accepted. The node's other input, position_sensor_command, has no writer here: its
inputs row says it waits for /navigation (WARN) and its log says so once.
"""

from __future__ import annotations

from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import pytest

pytestmark = [pytest.mark.dds, pytest.mark.slow]

PYTHON = sys.executable
PEER = Path(__file__).with_name('plain_dds_peer.py')
RATE = 340  # Hz the peer sends at
BARE = '_CREATED_BY_BARE_DDS_APP_'


class Lines:
    """A process's output lines, read on a thread as they come."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[str] = []
        threading.Thread(target=lambda: self.lines.extend(proc.stdout), daemon=True).start()

    def wait_for(self, start: str, timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in self.lines:
                if line.startswith(start):
                    return line.strip()
            time.sleep(0.05)
        raise AssertionError(f'no line {start!r} in {timeout} s: {self.lines[-20:]}')


@pytest.mark.timeout(300)
@pytest.mark.parametrize('named', [True, False], ids=['named_by_gid', 'not_named'])
def test_a_plain_dds_driver_is_admitted_by_its_gid_and_foreign_without(named):
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from agv_nodes import qos

    peer = subprocess.Popen([PYTHON, str(PEER)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    peer_out = Lines(peer)
    sensor = None
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('plain_dds_probe', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    rows: list[tuple[str, dict[str, str]]] = []  # position_sensor's inputs rows, in order

    def diagnostics(msg) -> None:
        for st in msg.status:
            if st.hardware_id == 'position_sensor' and st.name.endswith('/inputs'):
                rows.append((st.message, {kv.key: kv.value for kv in st.values}))
    node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics, qos.EVENTS)

    def spin_until(condition, timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            executor.spin_once(timeout_sec=0.05)
            assert time.monotonic() < deadline, (f'timed out waiting for {what}; last row '
                                                 f'{rows[-1:]}; sensor {sensor_out.lines[-10:]}')
    try:
        gid = peer_out.wait_for('gid ', 60).split()[1]
        params = ['-p', 'use_sim_time:=false']  # a board in the world's place: the wall clock
        if named:
            params += ['-p', f"record_writers:=['adc_snapshot=gid:{gid}']"]
        sensor = subprocess.Popen([str(Path(PYTHON).parent / 'position_sensor'), '--ros-args',
                                   *params], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True)
        sensor_out = Lines(sensor)
        peer_out.wait_for('matched', 60)
        # the graph's own account of the writer: the peer's GID, and no ROS node
        spin_until(lambda: any(bytes(i.endpoint_gid).hex() == gid for i in
                               node.get_publishers_info_by_topic('hw/position_sensor/adc')), 30,
                   "the peer's writer on the graph")
        shown = [(i.node_namespace, i.node_name) for i in
                 node.get_publishers_info_by_topic('hw/position_sensor/adc')
                 if bytes(i.endpoint_gid).hex() == gid]
        assert shown == [(BARE, BARE)], shown

        def counted(key: str) -> int:
            return int(rows[-1][1].get(f'adc_snapshot {key}', '0')) if rows else 0

        def foreign() -> int:
            text = rows[-1][1].get('adc_snapshot rejects by reason', 'none') if rows else 'none'
            return dict(item.split('=') for item in text.split(', ')).get(
                'foreign_writer', 0) if text != 'none' else 0
        # two seconds of the peer's stream, taken or refused
        spin_until(lambda: counted('accepted') + int(foreign()) >= 2 * RATE, 60,
                   'two seconds of records judged')
        message, values = rows[-1]
        print(f'named={named}: {values.get("adc_snapshot accepted")} accepted, '
              f'{values.get("adc_snapshot rejects by reason")}; writer '
              f'{values.get("adc_snapshot writer")}; {message}')
        if named:
            assert values['adc_snapshot rejects by reason'] == 'none', values
            assert values['adc_snapshot writer'].startswith(f'gid:{gid} ({gid})'), values
        else:
            assert counted('accepted') == 0, values
            assert values['adc_snapshot rejects by reason'].startswith('foreign_writer='), values
            assert f'{BARE}/{BARE} ({gid}), not the writer /world' in \
                values['adc_snapshot last rejection'], values
        # an input whose named writer is not there says so, in /diagnostics and once in the
        # log: the command (no navigation here), and unnamed, the snapshots (no world)
        waiting = {'position_sensor_command': '/navigation', **({} if named else
                                                                 {'adc_snapshot': '/world'})}
        spin_until(lambda: all(f'{record}: waiting for its writer {writer}' in rows[-1][0]
                               for record, writer in waiting.items()), 30,
                   f'the waiting inputs named: {waiting}')
        assert rows[-1][0].count('waiting for its writer') == len(waiting), rows[-1][0]

        def said_lines() -> list[str]:
            return [line for line in sensor_out.lines if 'waiting for its writer' in line]
        # the log line and the row come from one check but reach this probe by two paths (the
        # node's stdout, /diagnostics): wait for the log's lines, then count them
        spin_until(lambda: len(said_lines()) >= len(waiting), 30, f'the log to name {waiting}')
        executor.spin_once(timeout_sec=1.0)  # a line said twice would be there by now
        said = said_lines()
        assert len(said) == len(waiting), said
        assert all(any(f'{record}: waiting' in line for line in said) for record in waiting), \
            said
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        if sensor is not None:
            sensor.send_signal(signal.SIGINT)
            try:
                sensor.wait(timeout=20)
            except subprocess.TimeoutExpired:
                sensor.kill()
        peer.stdin.close()
        try:
            peer.wait(timeout=20)
        except subprocess.TimeoutExpired:
            peer.kill()
