"""VDA 5050 startPause / stopPause through the bridge to the lock-step 1983 truck.

The whole truck in lock step with its bridge core (test_vda5050_truck_state.BridgedTruck: the
records and report lines a bridge node reads), judged by the world's ground truth: a startPause
mid-order is RUNNING until the truck is at rest, then FINISHED with `paused` true (6.8.2's
table: "Vehicle stands still ... The AGV reports .paused: true"); stopPause FINISHED with
`paused` false, and the order completes where it was asked to. Every state validates against
the official 2.1.0 state schema.
"""

from __future__ import annotations

import json
from typing import Any

import pytest
from test_vda5050_truck_state import WAY, BridgedTruck, order

from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.report import final_stops
from agv_nodes.vda5050.bridge import BridgeCore
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(300)


def instant(*actions: tuple[str, str], header_id: int = 0) -> str:
    """Return an instantActions message as a master writes it: (actionType, actionId) each."""
    return json.dumps({
        'headerId': header_id, 'timestamp': '2026-01-01T00:00:00.000Z', 'version': '2.1.0',
        'manufacturer': 'agv_nodes', 'serialNumber': 'agv1',
        'actions': [{'actionType': kind, 'actionId': action_id, 'blockingType': 'HARD'}
                    for kind, action_id in actions]})


def status_of(state: dict[str, Any], action_id: str) -> str | None:
    return next((a['actionStatus'] for a in state['actionStates']
                 if a['actionId'] == action_id), None)


def test_start_and_stop_pause_mid_order():
    t = BridgedTruck(seed=3)
    t.apply(t.core.state_now(0.0))
    t.run(1.0)
    t.apply(t.core.on_message('order', order(WAY[:4], {}), t.h.now))
    vehicle = t.h.world.vehicle
    assert t.run(60.0, until=lambda: vehicle.state.speed > 0.6)
    sent = len(t.states)
    t.apply(t.core.on_message('instantActions', instant(('startPause', 'p1')), t.h.now))
    t.run(0.2)
    first = t.states[sent]  # the state the instant action made, the truck still rolling
    assert status_of(first, 'p1') == 'RUNNING' and first['paused'] is False
    assert t.run(10.0, until=lambda: status_of(t.states[-1], 'p1') == 'FINISHED')
    paused = t.states[-1]
    assert paused['paused'] is True and paused['driving'] is False
    assert abs(vehicle.state.speed) == 0.0  # the world: the truck stands
    assert paused['nodeStates'], 'the order is kept'
    where = vehicle.sensor_point
    t.run(10.0)
    assert vehicle.sensor_point == where and t.states[-1]['paused'] is True
    t.apply(t.core.on_message('instantActions', instant(('stopPause', 'r1'), header_id=1),
                              t.h.now))
    assert t.run(5.0, until=lambda: status_of(t.states[-1], 'r1') == 'FINISHED')
    assert t.states[-1]['paused'] is False
    assert t.run(120.0, until=lambda: not t.states[-1]['nodeStates']
                 and not t.states[-1]['driving'])
    assert t.states[-1]['lastNodeId'] == 'W2.1' and not t.states[-1]['errors']
    final = final_stops(t.h.events)[-1]
    assert final['marker'] == 'W2.1' and abs(final['error_mm']) <= 5, final
    assert not t.invalid


def test_stop_pause_without_a_pause_finishes_at_once_and_a_repeat_start_pause_too():
    t = BridgedTruck(seed=4)
    t.apply(t.core.state_now(0.0))
    t.run(1.0)
    t.apply(t.core.on_message('instantActions', instant(('stopPause', 'r0')), t.h.now))
    assert status_of(t.states[-1], 'r0') == 'FINISHED' and t.states[-1]['paused'] is False
    sent = len(t.states)
    t.apply(t.core.on_message('instantActions', instant(('startPause', 'p1'), header_id=1),
                              t.h.now))
    assert t.run(3.0, until=lambda: status_of(t.states[-1], 'p1') == 'FINISHED')
    # RUNNING first: at rest already, the truck is paused once rest_time has passed
    assert [status_of(s, 'p1') for s in t.states[sent:]][0] == 'RUNNING'
    assert t.states[-1]['paused'] is True
    t.apply(t.core.on_message('instantActions', instant(('startPause', 'p2'), header_id=2),
                              t.h.now))
    t.run(0.5)
    assert status_of(t.states[-1], 'p2') == 'FINISHED' and t.states[-1]['paused'] is True
    assert not t.invalid


def test_a_truck_that_cannot_pause_fails_start_pause():
    """The executive's `unable` (the camera truck's) fails a startPause RUNNING or new."""
    core = BridgeCore(track_graph(load_layout(layout_path('demo_1983'))), 'agv_nodes', 'agv1')
    core.on_message('instantActions', instant(('startPause', 'p1')), 0.0)
    assert core.state().action_states[0].action_status == 'RUNNING'
    core.on_report('truck cannot pause: its executive has no pause for this guidance', 1.0)
    core.on_message('instantActions', instant(('startPause', 'p2'), header_id=1), 2.0)
    state = core.state()
    assert [(a.action_id, a.action_status, a.result_description)
            for a in state.action_states] == [('p1', 'FAILED', 'this truck cannot pause'),
                                              ('p2', 'FAILED', 'this truck cannot pause')]
    assert state.paused is False
