"""The world's pacer: waits for a lagging writer, gives up on a dead one, counts lost samples."""

import pytest

from agv_nodes.world.pacing import GraphPacer


def pacer(**kw) -> GraphPacer:
    return GraphPacer(0.05, {'traction_drive': 0.01, 'position_sensor_status': 0.02}, 340.0,
                      consumers=('position_sensor_status',), **kw)


def test_nothing_lags_until_a_writer_has_been_heard():
    p = pacer()
    assert p.lagging(10.0) == []


def test_from_the_start_a_writer_not_heard_yet_is_waited_for_then_given_up():
    p = pacer()
    p.arrived('position_sensor_status', 0.0, 0, 0)
    p.start(0.0)
    assert p.lagging(0.05) == []
    assert p.lagging(0.061) == ['traction_drive']
    p.give_up(['traction_drive'])
    assert p.lagging(1.0) == ['position_sensor_status']  # heard at 0.0: start() leaves it
    p.arrived('position_sensor_status', 1.0, 340, 340)
    assert p.lagging(1.0) == []


def test_a_heartbeat_older_than_its_period_plus_max_lag_lags():
    p = pacer()
    p.arrived('traction_drive', 1.0)
    assert p.lagging(1.059) == []
    assert p.lagging(1.061) == ['traction_drive']
    p.arrived('traction_drive', 1.061)
    assert p.lagging(1.061) == []


def test_a_dead_writer_is_given_up_until_it_is_heard_again():
    p = pacer()
    p.arrived('traction_drive', 1.0)
    assert p.lagging(2.0) == ['traction_drive']
    assert p.give_up(['traction_drive']) == 0
    assert p.lagging(3.0) == []
    p.arrived('traction_drive', 3.0)
    assert p.lagging(3.5) == ['traction_drive']


def test_a_consumer_behind_the_world_samples_lags_even_with_fresh_heartbeats():
    p = pacer()
    p.arrived('position_sensor_status', 1.0, sample_count=340, world_samples=345)
    assert p.lagging(1.0) == []
    p.arrived('position_sensor_status', 1.02, sample_count=350, world_samples=380)
    assert p.lagging(1.02) == ['position_sensor_status']  # 30 samples behind > 17 allowed
    p.arrived('position_sensor_status', 1.02, sample_count=375, world_samples=380)
    assert p.lagging(1.02) == []


def test_route_following_is_paced_on_the_guide_wire_records_it_has_taken():
    # steering_command echoes its count of guide_wire records (100 Hz); its heartbeat is fresh,
    # but demands made from samples 100 ms old must hold the world (pacing.py).
    p = GraphPacer(0.01, {'steering_command': 0.01}, 340.0, clock_step=0.0088,
                   consumers=('steering_command',), consumer_rates={'steering_command': 100.0})
    p.arrived('steering_command', 2.0, sample_count=190, world_samples=192)
    assert p.lagging(2.0) == []  # 2 records behind: within (0.01 + 0.0088) s at 100 Hz
    p.arrived('steering_command', 2.01, sample_count=191, world_samples=201)
    assert p.lagging(2.01) == ['steering_command']
    assert p.behind('steering_command', 2.01) == pytest.approx(0.08)
    slack = GraphPacer(0.01, {'steering_command': 0.01}, 340.0, clock_step=0.0088,
                       consumers=('steering_command',), slack={'steering_command': 0.1},
                       consumer_rates={'steering_command': 100.0})
    slack.arrived('steering_command', 2.01, sample_count=191, world_samples=201)
    assert slack.lagging(2.01) == []  # an injected 0.1 s delay is not waited for


def test_the_sample_count_wraps_at_16_bits():
    p = pacer()
    p.arrived('position_sensor_status', 1.0, sample_count=65530, world_samples=65532)
    p.arrived('position_sensor_status', 1.02, sample_count=4, world_samples=65542)
    assert p.lagging(1.02) == []


def test_samples_that_never_arrive_are_accepted_and_counted_once():
    p = pacer()
    p.arrived('position_sensor_status', 1.0, sample_count=100, world_samples=100)
    p.arrived('position_sensor_status', 1.1, sample_count=110, world_samples=200)
    assert p.lagging(1.1) == ['position_sensor_status']
    lost = p.give_up(['position_sensor_status'])
    assert 80 <= lost <= 90 and p.lost_samples == lost
    p.arrived('position_sensor_status', 1.12, sample_count=117, world_samples=207)
    assert p.lagging(1.12) == []
    assert p.give_up([]) == 0 and p.lost_samples == lost


def test_max_lag_zero_never_waits():
    p = GraphPacer(0.0, {'traction_drive': 0.01}, 340.0)
    p.arrived('traction_drive', 0.0)
    assert p.lagging(100.0) == []
