"""The world's pacer: waits for a node whose progress lags, gives up on a dead one."""

import pytest

from agv_nodes.world.pacing import GraphPacer

NODES = ('navigation', 'traction')


def pacer(max_lag: float = 0.01) -> GraphPacer:
    return GraphPacer(max_lag, NODES, clock_step=0.01, period=0.02)


def test_the_allowance_is_max_lag_plus_the_progress_period_and_the_clock_step():
    assert pacer().allowance == pytest.approx(0.04)


def test_nothing_lags_until_the_world_starts_and_a_node_not_heard_yet_is_waited_for():
    p = pacer()
    assert p.lagging(10.0) == []
    p.progress('navigation', 0.0, 0.0)
    p.start(0.0)
    assert p.lagging(0.039) == []
    assert p.lagging(0.041) == ['navigation', 'traction']
    p.progress('traction', 0.04, 0.041)
    assert p.lagging(0.041) == ['navigation']


def test_a_node_lags_once_its_progress_is_older_than_the_allowance():
    p = pacer()
    p.start(1.0)
    for node in NODES:
        p.progress(node, 1.0, 1.0)
    assert p.lagging(1.039) == []
    p.progress('traction', 1.02, 1.041)
    assert p.lagging(1.041) == ['navigation']
    assert p.worst == {'navigation': 0.0, 'traction': pytest.approx(0.021)}


def test_a_dead_node_is_given_up_until_it_is_heard_again():
    p = pacer()
    p.start(1.0)
    assert p.lagging(2.0) == list(NODES)
    p.give_up(['traction'])
    assert p.lagging(3.0) == ['navigation']
    p.progress('traction', 3.0, 3.0)
    assert p.lagging(3.5) == ['navigation', 'traction']


def test_an_unknown_node_is_ignored_and_max_lag_zero_never_waits():
    p = pacer(max_lag=0.0)
    p.start(0.0)
    p.progress('world', 0.0, 0.0)
    assert p.lagging(100.0) == []


def test_a_node_not_heard_since_the_start_is_unheard_even_if_heard_before():
    """start_patience applies to a node until its first progress after the world moves."""
    p = pacer()
    p.progress('navigation', 0.0, 0.0)  # heard before the start: its last word stands
    p.start(0.0)
    assert p.unheard(list(NODES)) == ['navigation', 'traction']
    p.progress('traction', 0.05, 0.05)
    assert p.unheard(p.lagging(1.0)) == ['navigation']
    p.progress('navigation', 0.9, 1.0)
    assert p.unheard(list(NODES)) == []
