"""agv-fleet-sim gets the pause with its bridge cores: startPause / stopPause over MQTT.

The simulator's trucks are the lock-step cores and the bridge core the vda5050_bridge node runs
(test_fleet_sim's fixtures: three trucks on fleet_1983, mosquitto, the independent master of
test/vda5050_master.py). A startPause mid-order stops agv1 (its visualization, from the world),
FINISHED with paused true; the others stand as they stood; after stopPause the order ends at
its last node.
"""

from __future__ import annotations

import time

import pytest
from test_fleet_sim import AT_REST, WALL, _idle, broker, fleet_sim, master  # noqa: F401
from vda5050_master import action, path

pytestmark = pytest.mark.timeout(400)


def _action(state: dict, action_id: str) -> str | None:
    return next((a['actionStatus'] for a in state['actionStates'] if a['actionId'] == action_id),
                None)


def test_a_fleet_sim_truck_pauses_mid_order_and_completes_it_after_resume(
        fleet_sim, master):  # noqa: F811 (test_fleet_sim's fixtures)
    _sim, tap, _url = fleet_sim
    nodes, edges = path(['A1.1', 'A2', 'A2.1', 'A3', 'A3.1'])
    master.order('o1', 0, nodes, edges)
    master.wait_for('state', lambda s: s['lastNodeId'] == 'A2', WALL, 'A2 passed')
    master.instant(action('startPause', 'p1'))
    paused = master.wait_for('state', lambda s: _action(s, 'p1') == 'FINISHED', WALL,
                             'p1 FINISHED')
    assert paused['paused'] is True and paused['driving'] is False and paused['nodeStates']
    since = tap.of('agv1', 'visualization')[-1][0]  # simulated s
    deadline = time.monotonic() + WALL
    while tap.of('agv1', 'visualization')[-1][0] < since + 5.0:  # 5 simulated s of the pause
        assert time.monotonic() < deadline, 'the simulator did not go on'
        time.sleep(0.05)
    shown = [v for t, v in tap.of('agv1', 'visualization') if t > since]
    assert shown and all(abs(v['velocity']['vx']) < AT_REST for v in shown)
    master.instant(action('stopPause', 'r1'))
    resumed = master.wait_for('state', lambda s: _action(s, 'r1') == 'FINISHED', WALL,
                              'r1 FINISHED')
    assert resumed['paused'] is False
    done = master.wait_for('state', _idle('A3.1', 'o1'), WALL, 'order o1 done at A3.1')
    assert done['errors'] == []
