"""The radio stop over the real graph with traction in manual mode: the world's cut alone.

Traction's manual mode takes command byte 1 as the demand before any other check, bypassing
the radio stop (GETREF, Baker 1983, App. B.2.2), so with the truck driven by hand the world's
hardware cut (the radio-control stop in the drive's safety circuit) is the only protection.
No task asks for manual mode: the test names a stand-in as traction's command writer
(`record_writers`, as a hand controller's driver would be named) and drives manually from it;
the executive's commands are then foreign to traction. The whole graph runs (demo_1983, one
process per node, sim time; test/graph_probe.py). The lock-step twin, with the expected times
worked out from the parameters: test_hardware_cuts.py.

The stand-in writes every 20 ms of wall time on a world at half real time (10 ms of sim time,
against the graph's 120 ms command_timeout): its own scheduling has a wide margin.
"""

from __future__ import annotations

import time
from typing import Any

from graph_probe import GraphProbe
import pytest
from test_hardware_cuts import electruk_friction_deceleration

from agv_nodes.records import codec

pytestmark = [pytest.mark.dds, pytest.mark.slow]

MANUAL = {'manual': 1, 'manual_speed': 20, 'reverse': 0, 'demand': 30}  # byte 1: 41 %


class StandIn:
    """Writes traction_command from a node named as its writer, while the probe spins."""

    def __init__(self, g: GraphProbe) -> None:
        import rclpy

        from agv_nodes.ros_ports import RecordPublisher

        self.g = g
        self.node = rclpy.create_node('stand_in', context=g.context)
        self.pub = RecordPublisher(self.node, codec()['traction_command'])
        self.fields: dict[str, Any] = {'demand': 0}
        self._next = 0.0

    def until(self, condition, wall_limit: float, what: str) -> None:
        """Write every 20 ms and spin the probe until `condition()`."""
        g = self.g
        deadline = time.monotonic() + wall_limit
        while not condition():
            now = time.monotonic()
            if now >= self._next:
                self.pub.publish(self.fields)
                self._next = now + 0.02
            g.executor.spin_once(timeout_sec=0.005)
            dead = g.launch.poll()
            assert not dead, f'{dead} died while waiting for {what}'
            assert now < deadline, f'timed out waiting for {what}; reports {g.reports}'

    def for_sim(self, seconds: float, what: str) -> None:
        end = self.g.time + seconds
        self.until(lambda: self.g.time >= end, 60 + 4 * seconds, what)


@pytest.mark.timeout(420)
def test_radio_stop_stops_a_manually_driven_truck_over_the_graph(tmp_path, fault_table):
    from agv_nodes.ros_ports import RecordSubscription

    g = GraphProbe(tmp_path / 'logs', time_factor=0.5,
                   extra={'traction': ["record_writers:=['traction_command=stand_in']"]})
    hand = StandIn(g)
    try:
        statuses: list[tuple[float, dict]] = []
        RecordSubscription(g.node, codec()['traction_status'],
                           callback=lambda f: statuses.append((g.time, f)))
        g.spin_until(lambda: g.launch.moving.is_set(), 120, 'the graph')
        hand.until(lambda: 'traction' in g.inputs and hand.pub.subscription_count > 0, 60,
                   "traction's inputs row and the stand-in matched")
        # arm traction: 00H, then a demand (the trip latch's rule), then drive by hand
        hand.until(lambda: statuses and statuses[-1][1]['trip_cause'] == 'startup'
                   and g.counted('traction', 'traction_command accepted') > 0, 60,
                   'traction taking the 00H')
        hand.for_sim(0.2, 'the 00H')
        hand.fields = {'demand': 30, 'executive_priority': 1}
        hand.until(lambda: not statuses[-1][1]['tripped'], 60, 'traction armed')
        hand.fields = MANUAL
        hand.until(lambda: g.speed > 0.3 and statuses[-1][1]['source'] == 'manual', 120,
                   'the truck driven by hand')
        speed = g.speed
        at = g.at_exact_time(lambda: g.radio_stop(True))
        rest = speed / electruk_friction_deceleration()
        hand.for_sim(rest + 0.5, 'the truck to come to rest')
        cut = g.drive_off_ms(at, 0.2)
        assert g.speed <= 0.005, g.speed
        stopped = [e_t for e_t, e in g.events if e['event'] == 'stopped' and e_t > at]
        assert stopped and stopped[0] - at <= rest + 0.2, (stopped, rest)
        # traction kept driving throughout: manual, the radio stop seen and bypassed
        after = [f for t, f in statuses if t > at + 0.1]
        assert after and all(f['radio_stop'] == 1 and f['source'] == 'manual'
                             and f['armature_on'] == 1 for f in after), after[-1]
        hand.for_sim(1.0, 'the truck held')
        assert g.speed <= 0.005
        g.radio_stop(False)  # released: the hand controller's demand drives it again
        hand.until(lambda: g.speed > 0.1, 60, 'the truck moving again on release')
        fault_table.add('radio stop while driven by hand (manual mode, traction bypasses it; '
                        'DDS)', "the world's hardware cut stops the truck; release drives on",
                        f'drive off {cut} ms after, at rest {stopped[0] - at:.2f} s after '
                        f'from {speed:.2f} m/s')
    finally:
        hand.node.destroy_node()
        g.close()
