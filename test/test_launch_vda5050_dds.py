"""agv-launch --vda5050: the truck's bridge on the launcher's own MQTT broker, over DDS.

The launcher starts the vda5050_bridge node with the others and, with no broker named, an
embedded broker in a thread of its own process. A plain paho client (no code of the package on
its side) sees the truck come ONLINE with a retained factsheet, OFFLINE when the launch stops,
and then no broker at all: the broker stops after the nodes. A SIGKILLed launcher takes its
bridge and its broker with it. The option plumbing without DDS is in test_launch_file.py.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import socket
import subprocess
import sys
import time

from node_processes import alive, wait_until_on_the_graph
from paho.mqtt.client import Client, MQTTv311
from paho.mqtt.enums import CallbackAPIVersion
import pytest

from agv_nodes.mqtt.client import parse_mqtt_url

pytestmark = [pytest.mark.dds]

PREFIX = 'uagv/v2/agv_nodes/agv1'  # the manufacturer of parameters.yaml, the default serial


class Listener:
    """A paho client that queues (topic level, payload as JSON, retain flag) of what it hears."""

    def __init__(self, url: str, name: str, *topics: str) -> None:
        host, port = parse_mqtt_url(url)
        self.heard: queue.Queue[tuple[str, dict, bool]] = queue.Queue()
        self.client = Client(callback_api_version=CallbackAPIVersion.VERSION2, client_id=name,
                             protocol=MQTTv311)
        self.client.on_message = lambda _c, _u, m: self.heard.put(
            (m.topic.rsplit('/', 1)[1], json.loads(m.payload), bool(m.retain)))
        self.client.connect(host, port)
        self.client.loop_start()
        for level in topics:
            self.client.subscribe(f'{PREFIX}/{level}', 1)

    def wait_for(self, topic: str, condition, wall_limit: float, what: str) -> tuple[dict, bool]:
        """Return (message, retained) of the first message on `topic` meeting `condition`."""
        deadline = time.monotonic() + wall_limit
        seen = []
        while (left := deadline - time.monotonic()) > 0:
            try:
                name, doc, retained = self.heard.get(timeout=left)
            except queue.Empty:
                break
            seen.append((name, doc.get('connectionState'), retained))
            if name == topic and condition(doc):
                return doc, retained
        raise AssertionError(f'{what} not heard within {wall_limit:g} s; heard {seen}')

    def close(self) -> None:
        """Disconnect and stop paho's thread."""
        self.client.disconnect()
        self.client.loop_stop()


def _refuses(url: str) -> bool:
    host, port = parse_mqtt_url(url)
    try:
        socket.create_connection((host, port), timeout=2.0).close()
    except OSError:
        return True
    return False


@pytest.mark.timeout(120)
def test_the_launched_bridge_comes_online_on_the_launchers_broker():
    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch

    launch = Launch(Options(world='none', vda5050=True, quiet=True,
                            domain_id=int(os.environ['ROS_DOMAIN_ID'])))
    url = launch.mqtt_url
    assert launch.broker is not None and url.startswith('mqtt://127.0.0.1:')
    master = None
    try:
        master = Listener(url, 'test_launch_master', 'connection', 'factsheet')
        launch.start()
        online, _ = master.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE',
                                    60, 'ONLINE')
        assert (online['manufacturer'], online['serialNumber']) == ('agv_nodes', 'agv1')
        master.wait_for('factsheet', lambda f: True, 10, 'a factsheet')
        # a master control that comes later is given the factsheet the broker kept
        late = Listener(url, 'test_launch_late_master', 'factsheet')
        try:
            fact, retained = late.wait_for('factsheet', lambda f: True, 10, 'a kept factsheet')
        finally:
            late.close()
        assert retained and fact['serialNumber'] == 'agv1'
        assert fact['typeSpecification']['navigationTypes'] == ['PHYSICAL_LINE_GUIDED']
        assert launch.poll() == []
        launch.stop()
        # the bridge stops before the broker: its OFFLINE still reaches the master control
        master.wait_for('connection', lambda c: c['connectionState'] == 'OFFLINE', 10,
                        'OFFLINE')
        assert launch.exits['vda5050_bridge'] == 0, launch.lines[-20:]
        assert _refuses(url), f'the broker on {url} still accepts connections'
    finally:
        if master is not None:
            master.close()
        launch.stop()


AGV_LAUNCH = """
import os, time
from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch
launch = Launch(Options(world='none', vda5050=True, quiet=True, namespace='/killed_bridge',
                        serial_number='agv1', domain_id=int(os.environ['ROS_DOMAIN_ID'])))
launch.start()
print(launch.ready_file.parent, launch.mqtt_url, launch.procs['vda5050_bridge'].pid,
      ' '.join(str(p.pid) for p in launch.procs.values()), flush=True)
time.sleep(120)
"""


@pytest.mark.timeout(90)
def test_a_sigkilled_launcher_leaves_no_bridge_and_no_broker(tmp_path, fault_table):
    """A SIGKILLed launcher runs no clean-up, yet nothing of the fleet link is left.

    The bridge dies with its launcher (the child wrapper's parent-death signal), the broker
    with the launcher's process (it is one of its threads).
    """
    proc = subprocess.Popen([sys.executable, '-c', AGV_LAUNCH], stdout=subprocess.PIPE,
                            text=True, cwd=tmp_path)
    overrides, url, bridge, *pids = proc.stdout.readline().split()
    pids = [int(p) for p in pids]
    try:
        assert int(bridge) in pids and len(pids) == 8  # world none, no recorder, the bridge
        wait_until_on_the_graph(len(pids), 30.0, '/killed_bridge')
        assert all(alive(p) for p in pids) and not _refuses(url)
    except BaseException:  # not to the kill: leave nothing running on the domain
        for pid in [proc.pid, *pids]:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
        raise
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    killed = time.monotonic()
    shutil.rmtree(overrides, ignore_errors=True)  # the one thing a killed launcher leaves
    deadline = killed + 20.0
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)
    took = time.monotonic() - killed
    left = [p for p in pids if alive(p)]
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert int(bridge) not in left, 'the bridge outlived its launcher'
    assert not left, f'node processes outlived their launcher: {left}'
    assert _refuses(url), f'the broker on {url} outlived its launcher'
    fault_table.add('SIGKILL agv-launch --vda5050 with its bridge running',
                    'the bridge and every node end (SIGTERM from the kernel), the embedded '
                    'broker with the launcher',
                    f'all {len(pids)} gone {took:.1f} s after the kill, the broker at once')


@pytest.mark.timeout(300)
def test_a_master_drives_agv_launch_on_mosquitto_and_hears_the_last_will():
    """The independent master (test/vda5050_master.py) drives `agv-launch --vda5050`.

    On mosquitto: a pick at W0.1 and a drop at W2.1, then the bridge SIGKILLed: the broker
    sends its last will, CONNECTIONBROKEN. Every message the truck sent validates against the
    official 2.1.0 schemas.
    """
    from vda5050_master import Master, action, path

    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch
    from agv_nodes.mqtt.mosquitto import Mosquitto

    broker = Mosquitto()
    url = broker.start()
    launch = Launch(Options(vda5050=True, mqtt_url=url, quiet=True,
                            domain_id=int(os.environ['ROS_DOMAIN_ID'])))
    master = None
    try:
        master = Master(url, 'agv_nodes', 'agv1')
        launch.start()
        master.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE', 60, 'ONLINE')
        nodes, edges = path(['L0', 'W0.1', 'L2', 'W2.1'],
                            actions={'W0.1': [action('pick', 'pick1')],
                                     'W2.1': [action('drop', 'drop1')]})
        master.order('o1', 0, nodes, edges)
        taken = master.wait_for('state', lambda s: s['orderId'] == 'o1', 30, 'order o1')
        assert taken['lastNodeId'] == '' and not taken['errors']
        master.wait_for('state', lambda s: any(a['actionId'] == 'drop1'
                                               and a['actionStatus'] == 'FINISHED'
                                               for a in s['actionStates']), 200, 'drop1 done')
        empty = master.wait_for('state', lambda s: s['lastNodeId'] == 'W2.1'
                                and s.get('loads') == [], 10, 'the load dropped')
        assert empty['nodeStates'] == [] and empty['agvPosition']['positionInitialized']
        assert any(s.get('loads') == [{'loadPosition': 'first'}] for s in master.states())
        assert launch.poll() == []
        os.kill(launch.procs['vda5050_bridge'].pid, signal.SIGKILL)
        master.wait_for('connection', lambda c: c['connectionState'] == 'CONNECTIONBROKEN', 30,
                        'the last will')
        assert master.received['visualization']
        assert master.invalid == [], master.invalid[:5]
    finally:
        if master is not None:
            master.close()
        launch.stop()
        broker.stop()
