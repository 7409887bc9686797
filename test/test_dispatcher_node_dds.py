"""The dispatcher node in its own process: transports over DDS, the trucks over MQTT.

Real parts: the `dispatcher` console script (rclpy, Fast DDS), mosquitto, and a
truck played by the test as its bridge answers (test_dispatcher_mqtt.PlayedTruck). The test's
own node writes `fleet/transport` and reads `fleet/report` and /diagnostics.

Hand-shakes: what a writer sends before its reader has matched is lost, so the test first
waits for both matches, then sends a bad transport until its rejection comes back (the report
writer has matched the test's reader too); and it starts the truck once the node's
/diagnostics says its MQTT link is up (a state sent before the dispatcher subscribed is lost:
QoS 0, not retained).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
import signal
import subprocess
import time

import pytest
from test_dispatcher_mqtt import PlayedTruck

from conftest import PYTHON

pytestmark = pytest.mark.dds
DISPATCHER = str(Path(PYTHON).parent / 'dispatcher')
ROW = 'agv/dispatcher/fleet'


@pytest.mark.timeout(120)
def test_transports_over_dds_are_answered_assigned_and_sent_to_the_truck(tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.fleet.track_graph import track_graph
    from agv_nodes.mqtt.mosquitto import Mosquitto
    from agv_nodes.vda5050.codec import parse
    from agv_nodes.vda5050.order import Order
    from agv_nodes.world.layout import layout_path, load_layout

    graph = track_graph(load_layout(layout_path('demo_1983')))
    broker = Mosquitto()
    url = broker.start()
    log = open(tmp_path / 'dispatcher.log', 'w+')  # noqa: SIM115 - read at the end
    proc = subprocess.Popen(
        [DISPATCHER, '--ros-args', '-p', f'mqtt_url:={url}', '-p', 'trucks:=[agv1, agv2]',
         '-p', 'period:=0.05'], stdout=log, stderr=subprocess.STDOUT, text=True)
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node('dispatcher_probe', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    lines: list[str] = []
    rows: list[dict[str, str]] = []
    truck: PlayedTruck | None = None

    def on_row(msg: DiagnosticArray) -> None:
        rows.extend({'level': int.from_bytes(s.level), 'message': s.message,
                     **{kv.key: kv.value for kv in s.values}}
                    for s in msg.status if s.name == ROW)

    transport = node.create_publisher(String, 'fleet/transport', qos.EVENTS)
    report = node.create_subscription(String, 'fleet/report', lambda m: lines.append(m.data),
                                      qos.EVENTS)
    node.create_subscription(DiagnosticArray, '/diagnostics', on_row, qos.EVENTS)

    def said() -> str:
        log.seek(0)
        return log.read()[-3000:]

    def spin_until(condition: Callable[[], bool], wall_limit: float, what: str) -> None:
        deadline = time.monotonic() + wall_limit
        while not condition():
            assert proc.poll() is None, f'the dispatcher ended ({proc.returncode}): {said()}'
            assert time.monotonic() < deadline, \
                f'no {what} within {wall_limit:g} s; report {lines}; rows {rows[-1:]}\n{said()}'
            executor.spin_once(timeout_sec=0.02)
            if truck is not None:
                truck.pump()

    try:
        spin_until(lambda: transport.get_subscription_count() > 0
                   and report.get_publisher_count() > 0, 60, 'match with the dispatcher')
        bad = "rejected 'W9 to W2': unknown station 'W9' (stations: W0, W1, W2, W3)"
        sent = [-1.0]
        sends = [0]  # each reaches the matched dispatcher; a report before our match is lost

        def rejected() -> bool:  # sent again until the report writer has matched our reader
            if bad in lines:
                return True
            if time.monotonic() - sent[0] > 0.5:
                transport.publish(String(data='W9 to W2'))
                sent[0] = time.monotonic()
                sends[0] += 1
            return False

        spin_until(rejected, 30, 'the rejection of W9 to W2')
        spin_until(lambda: rows and rows[-1]['connected'] == 'True', 30, 'the broker connected')

        truck = PlayedTruck(url, graph, 'agv1', 'W3.1')
        spin_until(lambda: rows[-1]['trucks heard'] == '1', 30, "agv1's state taken")
        transport.publish(String(data='W0 to W2'))
        spin_until(lambda: 't1: assigned to agv1' in lines, 30, 't1 assigned')
        assert lines[-2:] == ['t1: accepted: W0 to W2', 't1: assigned to agv1']
        spin_until(lambda: truck.received['order'], 10, "t1's order at agv1")
        order = parse(Order, truck.received['order'][0])
        assert (order.order_id, order.nodes[0].node_id) == ('t1', 'W3.1')

        transport.publish(String(data='status'))  # a query: answered, nothing changes
        spin_until(lambda: lines[-1].startswith('status:'), 10, 'the answer to status')
        assert lines[-1].startswith('status: 0 queued, 1 assigned, 0 done, 0 failed; trucks '
                                    'heard 1, online ')
        spin_until(lambda: rows[-1]['orders sent'] == '1', 10, 'the order in /diagnostics')
        row = rows[-1]
        assert int(row['transports rejected']) == sends[0] >= lines.count(bad) >= 1
        assert (row['assignments'], row['queue'], row['done'], row['failed'],
                row['deadlocks'], row['messages rejected']) == ('1', '0', '0', '0', '0', '0')
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0, said()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        if truck is not None:
            truck.link.close()
        executor.shutdown()
        node.destroy_node()  # now, not at some later test's garbage collection
        rclpy.try_shutdown(context=context)
        broker.stop()
        log.close()


@pytest.mark.timeout(60)
@pytest.mark.parametrize('given, words', [
    (["positions:=['agv3:W0.1']"], "parameter 'positions' = 'agv3:W0.1': 'agv3' is not one of "
                                   "trucks ['agv1']"),
    (["parking:=['agv1:L0']"], "parameter 'parking' = 'agv1:L0': 'L0' is no stop marker"),
    (['period:=0.0'], "parameter 'period' = 0.0: outside 0.01..10.0"),
    (['mqtt_url:=http://host'], "parameter 'mqtt_url' = 'http://host': not an mqtt:// URL"),
])
def test_a_bad_parameter_stops_the_dispatcher_with_one_line(given, words):
    args = [DISPATCHER, '--ros-args', '-p', 'mqtt_url:=mqtt://127.0.0.1:1']
    for g in given:
        args += ['-p', g]
    res = subprocess.run(args, capture_output=True, text=True, timeout=50)
    assert res.returncode == 2, res.stdout + res.stderr
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith('dispatcher: ') and words in line, line
