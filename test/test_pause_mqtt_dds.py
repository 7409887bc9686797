"""A VDA 5050 master pauses the 1983 truck mid-order and resumes it: MQTT one side, DDS the other.

Real parts end to end: mosquitto, `agv-launch --vda5050` (the truck's whole graph over DDS, one
process per node, the world on demo_1983, and its vda5050_bridge node), and the master control
written apart from the bridge (test/vda5050_master.py), which checks every message the truck
sends against the standard's JSON schema. startPause mid-order is RUNNING, then FINISHED with
`paused` true once the truck stands; the world's ground truth (its pose) says it does, and
stays so; stopPause is FINISHED with `paused` false and the order ends at its last node.
"""

from __future__ import annotations

from graph_probe import AT_REST, GraphProbe
import pytest
from vda5050_master import Master, action, path

from agv_nodes.report import final_stops

pytestmark = [pytest.mark.dds]


def _action(state: dict, action_id: str) -> str | None:
    return next((a['actionStatus'] for a in state['actionStates'] if a['actionId'] == action_id),
                None)


@pytest.mark.timeout(300)
def test_a_master_pauses_the_truck_mid_order_and_the_order_completes_after_resume(tmp_path):
    from agv_nodes.mqtt.mosquitto import Mosquitto

    broker = Mosquitto()
    url = broker.start()
    g = GraphProbe(tmp_path / 'logs', layout='demo_1983', vda5050=True, mqtt_url=url)
    master = None
    try:
        master = Master(url, 'agv_nodes', 'agv1')

        def spin() -> None:
            assert g.launch.poll() == [], g.launch.lines[-20:]
            g.executor.spin_once(timeout_sec=0.05)

        master.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE', 60,
                        'ONLINE', spin)
        master.wait_for('state', lambda s: True, 10, 'a first state', spin)
        g.ready()
        nodes, edges = path(['L0', 'W0.1', 'L2', 'W2.1'])
        master.order('o1', 0, nodes, edges)
        master.wait_for('state', lambda s: s['lastNodeId'] == 'W0.1', 90, 'W0.1 passed', spin)
        g.spin_until(lambda: g.speed > 0.5, 30, 'the truck at speed')

        master.instant(action('startPause', 'p1'))
        running = master.wait_for('state', lambda s: _action(s, 'p1') is not None, 20,
                                  'p1 taken', spin)
        assert _action(running, 'p1') == 'RUNNING' and running['paused'] is False
        paused = master.wait_for('state', lambda s: _action(s, 'p1') == 'FINISHED', 30,
                                 'p1 FINISHED', spin)
        assert paused['paused'] is True and paused['driving'] is False
        assert paused['orderId'] == 'o1' and paused['nodeStates'], 'the order is kept'
        assert g.speed <= AT_REST  # the world: the truck stands
        since = g.time
        g.spin_until(lambda: g.time >= since + 5.0, 60, '5 s of the pause')
        assert g.travelled_since(since) <= 0.001  # a millimetre of pose noise at most
        assert master.states()[-1]['paused'] is True

        master.instant(action('stopPause', 'r1'))
        resumed = master.wait_for('state', lambda s: _action(s, 'r1') == 'FINISHED', 30,
                                  'r1 FINISHED', spin)
        assert resumed['paused'] is False
        done = master.wait_for('state', lambda s: s['headerId'] > resumed['headerId']
                               and s['nodeStates'] == [] and not s['driving'], 120,
                               'the order ended', spin)
        assert done['lastNodeId'] == 'W2.1' and not done['errors']
        g.stays_at_rest(1.0)
        final = final_stops([{**e, 'time': t} for t, e in g.events])[-1]
        assert final['marker'] == 'W2.1' and abs(final['error_mm']) <= 5, final
        assert master.invalid == [], master.invalid[:5]  # every message valid by the schema
    finally:
        if master is not None:
            master.close()
        g.close()
        broker.stop()
