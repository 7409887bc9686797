"""A VDA 5050 master drives the 1983 truck through its bridge: MQTT one side, DDS the other.

Real parts end to end: mosquitto, the truck's whole graph over DDS (one process
per node, the world on demo_1983), the vda5050_bridge node in its own process, and a master
control written apart from the bridge (test/vda5050_master.py) that checks every message the
truck sends against the standard's JSON schema. The master sends bad orders, an order with a
pick and a drop, an update that stitches on at the end of the base, and a cancel; the world's
ground truth (load_moved events, the truck at rest) says the truck did what the states say.
"""

from __future__ import annotations

from pathlib import Path
import signal
import subprocess

from graph_probe import AT_REST, GraphProbe
import pytest
from vda5050_master import Master, action, path

from conftest import PYTHON

pytestmark = [pytest.mark.dds, pytest.mark.slow]
BRIDGE = str(Path(PYTHON).parent / 'vda5050_bridge')


def _errors(state: dict, kind: str) -> list[dict]:
    return [e for e in state['errors'] if e['errorType'] == kind]


def _references(error: dict) -> dict[str, str]:
    return {r['referenceKey']: r['referenceValue'] for r in error.get('errorReferences', [])}


def _action(state: dict, action_id: str) -> str | None:
    return next((a['actionStatus'] for a in state['actionStates'] if a['actionId'] == action_id),
                None)


@pytest.mark.timeout(300)
def test_a_master_drives_the_truck_through_orders_an_update_a_cancel_and_bad_input(tmp_path):
    from agv_nodes.mqtt.mosquitto import Mosquitto

    broker = Mosquitto()
    url = broker.start()
    g = GraphProbe(tmp_path / 'logs', layout='demo_1983')
    bridge = subprocess.Popen(
        [BRIDGE, '--ros-args', '-p', f'mqtt_url:={url}', '-p', 'serial_number:=agv1'],
        env=g.launch.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    master = None
    try:
        master = Master(url, 'agv_nodes', 'agv1')

        def spin() -> None:
            assert bridge.poll() is None, bridge.communicate(timeout=10)[0][-3000:]
            g.executor.spin_once(timeout_sec=0.05)

        master.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE', 60,
                        'ONLINE', spin)
        fact = master.wait_for('factsheet', lambda f: True, 10, 'a factsheet', spin)
        assert fact['typeSpecification']['navigationTypes'] == ['PHYSICAL_LINE_GUIDED']
        first = master.wait_for('state', lambda s: True, 10, 'a first state', spin)
        assert (first['orderId'], first['lastNodeId'], first['nodeStates']) == ('', '', [])
        g.ready()

        # not VDA 5050: a validationError naming the missing fields, nothing driven
        master.raw('order', '{"headerId": 1, "orderId": "x"}')
        bad = master.wait_for('state', lambda s: _errors(s, 'validationError'), 20,
                              'a validationError', spin)
        refs = _references(_errors(bad, 'validationError')[0])
        assert refs['topic'] == 'order' and {'nodes', 'edges', 'orderUpdateId'} <= set(refs)

        # valid, but a node the floor does not have: orderError naming it
        nodes, edges = path(['L0', 'W0.1', 'L9'])
        master.order('bad', 0, nodes, edges)
        bad = master.wait_for('state', lambda s: _errors(s, 'orderError'), 20, 'an orderError',
                              spin)
        assert 'L9' in _references(_errors(bad, 'orderError')[0]).values()
        assert bad['orderId'] == ''  # rejected: nothing taken over

        # load at W0 (the first conveyor), take it to W2 and unload it there
        nodes, edges = path(['L0', 'W0.1', 'L2', 'W2.1'],
                            actions={'W0.1': [action('pick', 'pick1')],
                                     'W2.1': [action('drop', 'drop1')]})
        master.order('o1', 0, nodes, edges)
        taken = master.wait_for('state', lambda s: s['orderId'] == 'o1', 20, 'order o1', spin)
        assert not taken['errors']  # an accepted order clears the rejections
        # 6.10.6: the truck has read no card yet; L0, the first ahead, is still to traverse
        assert taken['lastNodeId'] == '' and taken['nodeStates'][0]['nodeId'] == 'L0'
        assert taken['agvPosition']['positionInitialized'] is False
        assert taken.get('loads') == []  # load handling heard: both conveyors empty
        at_l0 = master.wait_for('state', lambda s: s['lastNodeId'] == 'L0', 60, 'L0 read', spin)
        assert at_l0['agvPosition']['positionInitialized'] is True
        assert [n['nodeId'] for n in at_l0['nodeStates']] == ['W0.1', 'L2', 'W2.1']
        picked = master.wait_for('state', lambda s: _action(s, 'pick1') == 'FINISHED', 150,
                                 'pick1 FINISHED', spin)
        # the conveyor's sensor and the task's end come by different paths: the next states
        master.wait_for('state', lambda s: s['headerId'] >= picked['headerId']
                        and s['loads'] == [{'loadPosition': 'first'}], 10, 'the load on', spin)
        done = master.wait_for(
            'state', lambda s: _action(s, 'drop1') == 'FINISHED', 150, 'drop1 FINISHED', spin)
        assert (done['lastNodeId'], done['nodeStates'], done['edgeStates']) == ('W2.1', [], [])
        # the conveyor's sensor and the task's end come by different paths: the next states
        empty = master.wait_for('state', lambda s: s['headerId'] >= done['headerId']
                                and s['loads'] == [], 10, 'the load gone', spin)
        assert empty['lastNodeId'] == 'W2.1'
        moved = [e for _t, e in g.events if e['event'] == 'load_moved']
        assert len(moved) == 2, moved  # the world's ground truth: on at W0, off at W2

        # an update stitched on at W2.1 (sequenceId 6): on round to W1's stop marker
        nodes, edges = path(['W2.1', 'W2.2', 'L1', 'W1.1'], first_sequence=6)
        master.order('o1', 1, nodes, edges)
        master.wait_for('state', lambda s: s['orderUpdateId'] == 1 and s['driving'], 30,
                        'update 1 driving', spin)
        # W2.2, a stop marker driven past, is lastNodeId as the truck passes it, L1 still ahead
        passed = master.wait_for('state', lambda s: s['lastNodeId'] == 'W2.2', 60,
                                 'W2.2 passed', spin)
        assert [n['nodeId'] for n in passed['nodeStates']] == ['L1', 'W1.1']
        assert passed['driving'] and passed['lastNodeSequenceId'] == 8
        g.spin_until(lambda: g.speed > 0.3, 60, 'the truck under way')
        master.instant({'actionType': 'cancelOrder', 'actionId': 'cancel1',
                        'blockingType': 'HARD'})
        cancelled = master.wait_for('state', lambda s: _action(s, 'cancel1') == 'FINISHED', 60,
                                    'cancel1 FINISHED', spin)
        assert cancelled['nodeStates'] == [] and not cancelled['driving']
        g.spin_until(lambda: g.speed < AT_REST, 30, 'the truck at rest')

        # an update older than the one running: orderUpdateError, nothing changes
        nodes, edges = path(['W2.1', 'W2.2'], first_sequence=6)
        master.order('o1', 0, nodes, edges)
        late = master.wait_for('state', lambda s: _errors(s, 'orderUpdateError'), 20,
                               'an orderUpdateError', spin)
        assert late['orderUpdateId'] == 1

        shown = [v for v in master.received['visualization']
                 if v['agvPosition']['positionInitialized']]
        assert shown and all(s['safetyState'] == {'eStop': 'NONE', 'fieldViolation': False}
                             for s in master.states())
        assert master.invalid == [], master.invalid[:5]  # every message valid by the schema
        bridge.send_signal(signal.SIGINT)
        out, _ = bridge.communicate(timeout=30)
        assert bridge.returncode == 0, out
        master.wait_for('connection', lambda c: c['connectionState'] == 'OFFLINE', 10,
                        'OFFLINE', spin)
    finally:
        if bridge.poll() is None:
            bridge.kill()
            bridge.communicate(timeout=10)
        if master is not None:
            master.close()
        g.close()
        broker.stop()


@pytest.mark.timeout(300)
def test_broker_lost_mid_order_the_truck_ends_its_base_and_the_master_hears_the_gap(tmp_path):
    """The broker stops while the truck drives; the truck goes on without it.

    It finishes the released base and waits at the decision point; once the broker is back the
    bridge reconnects and reports the gap.
    """
    from agv_nodes.mqtt.mosquitto import Mosquitto

    broker = Mosquitto()
    url = broker.start()
    port = broker.port
    g = GraphProbe(tmp_path / 'logs', layout='demo_1983')
    bridge = subprocess.Popen(
        [BRIDGE, '--ros-args', '-p', f'mqtt_url:={url}', '-p', 'reconnect_max:=1.0'],
        env=g.launch.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    master = None
    try:
        master = Master(url, 'agv_nodes', 'agv1')

        def spin() -> None:
            assert bridge.poll() is None, bridge.communicate(timeout=10)[0][-3000:]
            g.executor.spin_once(timeout_sec=0.05)

        master.wait_for('connection', lambda c: c['connectionState'] == 'ONLINE', 60,
                        'ONLINE', spin)
        g.ready()
        # base: load at W0, unload at W2.1 (the decision point); horizon: on to W1.1
        nodes, edges = path(['L0', 'W0.1', 'L2', 'W2.1', 'W2.2', 'L1', 'W1.1'], released=4,
                            actions={'W0.1': [action('pick', 'pick1')],
                                     'W2.1': [action('drop', 'drop1')]})
        master.order('o2', 0, nodes, edges)
        master.wait_for('state', lambda s: s['orderId'] == 'o2' and s['driving'], 30,
                        'order o2 driving', spin)
        broker.stop()
        down = g.time
        # without a master the truck does what it was given, and no more
        g.spin_until(lambda: len([e for _t, e in g.events if e['event'] == 'load_moved']) == 2,
                     150, 'the load picked at W0 and dropped at W2')
        g.stays_at_rest(hold=2.0, what='at the decision point')
        broker = Mosquitto(port=port)
        broker.start()
        back = master.wait_for(
            'state', lambda s: any(i['infoType'] == 'brokerConnectionGap'
                                   for i in s.get('information', [])), 60, 'the gap', spin)
        assert back['lastNodeId'] == 'W2.1' and _action(back, 'drop1') == 'FINISHED'
        assert [n['nodeId'] for n in back['nodeStates']] == ['W2.2', 'L1', 'W1.1']
        assert not any(n['released'] for n in back['nodeStates']) and not back['driving']
        assert back['newBaseRequest'] is True
        onlines = [c for c in master.received['connection'] if c['connectionState'] == 'ONLINE']
        assert len(onlines) == 2  # once at the start, once after the broker came back
        print(f'broker down at {down:.1f} s sim; back: {back["information"]}')
        assert master.invalid == [], master.invalid[:5]
    finally:
        if bridge.poll() is None:
            bridge.send_signal(signal.SIGINT)
            try:
                bridge.communicate(timeout=20)
            except subprocess.TimeoutExpired:
                bridge.kill()
                bridge.communicate(timeout=10)
        if master is not None:
            master.close()
        g.close()
        broker.stop()
