"""A node's time and distance.

ClockTimers (FIFO /clock under the EventsExecutor) and the wheel encoders' odometer. No DDS:
the /clock reader is fed directly.
"""

from __future__ import annotations

from typing import Any

import pytest
import rclpy
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock

from agv_nodes.core_node import ClockTimers
from agv_nodes.node_process import make_executor
from agv_nodes.odometry import Odometer, counter_step

MS = 1_000_000  # ns


class _Node:
    """Only what ClockTimers asks of a node: one subscription."""

    def __init__(self) -> None:
        self.callback = None

    def create_subscription(self, _type: Any, topic: str, callback, _qos: Any,
                            raw: bool = False) -> None:
        assert topic == '/clock' and raw  # taken serialized (agv_nodes.records.carrier)
        self.callback = callback


def _clock(ns: int) -> bytes:
    """Return a /clock sample as the reader takes it: serialized by rclpy's own serializer."""
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(ns, 1_000_000_000)
    return serialize_message(msg)


def _timers(*periods: float) -> tuple[ClockTimers, _Node, dict[float, list[int]]]:
    node = _Node()
    # a 1 s jump limit: the 490 ms step below is a step, not a jump (agv_nodes/clock_jump.py)
    timers = ClockTimers(node, jump_limit=1.0, check_writer=False)
    fired: dict[float, list[int]] = {p: [] for p in periods}
    for p in periods:
        timers.add(p, lambda p=p: fired[p].append(timers.now_ns))
    return timers, node, fired


def test_callbacks_are_due_every_period_at_most_once_per_clock_message():
    timers, node, fired = _timers(0.010, 0.050)
    assert timers.now_ns is None
    step = 8_823_529  # /clock every 3rd sample at 340 Hz
    for k in range(1, 60):
        node.callback(_clock(1_000 * MS + k * step))
    assert timers.now_ns == 1_000 * MS + 59 * step
    # 10 ms due times met by 8.8 ms steps: never twice in one step, none lost but the
    # periods a step passed over entirely (as a rclpy timer under sim time)
    ten = fired[0.010]
    assert all(b - a >= step for a, b in zip(ten, ten[1:], strict=False))
    assert 44 <= len(ten) <= 51  # 58 steps x 8.8 ms = 512 ms
    fifty = fired[0.050]
    assert len(fifty) == 10
    assert all(44 * MS <= b - a <= 53 * MS for a, b in zip(fifty, fifty[1:], strict=False))


def test_a_long_step_skips_the_periods_it_passed_and_time_going_back_is_absorbed():
    timers, node, fired = _timers(0.010)
    node.callback(_clock(1_000 * MS))  # first sample: starts the timer, no call
    node.callback(_clock(1_010 * MS))
    node.callback(_clock(1_500 * MS))  # a 490 ms step: one call, not 49
    node.callback(_clock(1_505 * MS))
    node.callback(_clock(1_510 * MS))
    assert fired[0.010] == [1_010 * MS, 1_500 * MS, 1_510 * MS]
    node.callback(_clock(5 * MS))  # a respawned world: its clock jumped back
    node.callback(_clock(10 * MS))  # the node's time runs on from where it stood
    node.callback(_clock(15 * MS))
    assert fired[0.010][3:] == [1_520 * MS]
    assert [j.back for j in timers.rule.jumps] == [True]
    node.callback(_clock(0))  # a clock that has not started is not time
    assert timers.now_ns == 1_520 * MS


def test_counter_steps_wrap_both_ways():
    assert counter_step(100, 130) == 30
    assert counter_step(65_530, 4) == 10  # forward through the wrap
    assert counter_step(4, 65_530) == -10  # reversing through it
    assert counter_step(0, 0) == 0


def test_the_odometer_counts_the_mean_of_the_two_wheels_in_metres():
    odo = Odometer()
    assert odo.update(65_000, 100) == 0.0  # the first reading only sets the origin
    odo.update(65_500, 560)  # left +500, right +460 mm
    assert odo.metres == pytest.approx(0.480)
    odo.update(464, 1_060)  # left +500 through the wrap, right +500
    assert odo.metres == pytest.approx(0.980)
    odo.update(65_000, 60)  # both back 1 m through the wrap (reversing)
    assert odo.metres == pytest.approx(-0.020)


@pytest.mark.parametrize('kind', ['events', 'single'])
def test_both_executors_can_be_made(kind: str):
    rclpy.init()
    try:
        executor = make_executor(kind)
        assert ('Events' in type(executor).__name__) == (kind == 'events')
        executor.shutdown()
    finally:
        rclpy.try_shutdown()


def test_clock_timers_replace_the_time_sources_reader_and_set_the_ros_clock():
    """One /clock reader per node (ClockTimers'), and get_clock() follows it."""
    from rclpy.parameter import Parameter

    rclpy.init()
    try:
        node = rclpy.create_node('clock_timers_test',
                                 parameter_overrides=[Parameter('use_sim_time', value=True)])
        clock_readers = [s for s in node.subscriptions if s.topic_name == '/clock']
        assert len(clock_readers) == 1  # rclpy's TimeSource
        timers = ClockTimers(node)
        # rclpy's is gone; ClockTimers' takes each sample with its writer's GID (a waitable)
        assert not [s for s in node.subscriptions if s.topic_name == '/clock']
        assert timers._tagged is not None and timers._tagged.waitable in node.waitables
        timers._on_clock(_clock(1_234 * MS))
        assert node.get_clock().now().nanoseconds == 1_234 * MS == timers.now_ns
        node.destroy_node()
    finally:
        rclpy.try_shutdown()


def test_the_world_sets_its_own_ros_clock_as_it_publishes_clock_with_no_reader_of_its_own():
    """The world's ROS clock is set where it writes /clock, not read back over DDS.

    Reading it back woke the world's loop at every clock step, and spun it thousands of times
    a second while it waited for its peers.
    """
    from agv_nodes.world.node import WorldNode

    rclpy.init(args=['--ros-args', '-p', 'use_sim_time:=true', '-p', 'publish_clock:=true'])
    try:
        world = WorldNode()
        assert not [s for s in world.subscriptions if s.topic_name == '/clock']
        for _ in range(340):  # one simulated second
            world.core.step()
        world.publish_clock_now()
        assert world.get_clock().now().nanoseconds == round(world.time * 1e9) == 1_000_000_000
        world.destroy_node()
    finally:
        rclpy.try_shutdown()
