"""The dispatcher on the two-loop floor (loops_1983), trucks in lock step through their bridges.

The floor's crossover makes a second, shorter loop (agv_nodes.world.loops_floor): the
dispatcher plans each way on both loops and takes the shorter, and its watchdog re-routes a
truck stuck behind trucks that cannot move (off the broker, or deadlocked with it) round the
other loop (agv_nodes.fleet.reroute).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from agv_nodes.fleet.bridged import BridgedFleet
from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.reroute import REROUTE_AFTER
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.world.fleet_floor import programme_loads
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(600)

LAYOUT = 'loops_1983'


@pytest.fixture
def dispatched() -> Iterator[Callable[[dict[str, str]], tuple[Fleet, Dispatcher, BridgedFleet]]]:
    """Return a maker of trucks set down at `positions`, their dispatcher and the run.

    The dispatcher parks them where they were set down. The trucks are stepped in two
    processes, which run as one does (test_fleet_processes.py).
    """
    fleets: list[Fleet] = []

    def make(positions: dict[str, str]) -> tuple[Fleet, Dispatcher, BridgedFleet]:
        lay = load_layout(layout_path(LAYOUT))
        at = {m.name: (m.path, m.at) for m in lay.markers}
        fleet = Fleet(LAYOUT, [at[p] for p in positions.values()], names=list(positions),
                      processes=2)
        fleets.append(fleet)
        graph = track_graph(lay)
        dispatcher = Dispatcher(graph, fleet.names, positions=positions, parking=positions)
        return fleet, dispatcher, BridgedFleet(fleet, dispatcher, graph=graph)

    yield make
    for fleet in fleets:
        fleet.close()


def released_edges(run: BridgedFleet) -> list[tuple[str, str | None]]:
    """Return every released edge of every order sent, with its direction."""
    return [(e.edge_id, e.direction) for _, _, topic, message in run.sent if topic == 'order'
            for e in message.edges if e.released]


def test_four_trucks_carry_their_loads_on_both_loops_without_a_collision(dispatched):
    lay = load_layout(layout_path(LAYOUT))
    positions = {f'agv{k + 1}': place for k, place in enumerate(lay.parking[:4])}
    fleet, dispatcher, run = dispatched(positions)
    loads = programme_loads(lay.stations, 4)
    for load, (source, destination) in loads.items():
        dispatcher.submit(TransportOrder(load, source, destination))
    assert run.run(900.0, until=lambda: len(dispatcher.done) == 4
                   or bool(dispatcher.failed or fleet.collisions)), run.summary()
    assert (dispatcher.failed, fleet.collisions, dispatcher.deadlocks) == ([], [], [])
    assert sorted(dispatcher.done) == sorted(loads)
    for load, (_, destination) in loads.items():
        assert fleet.station_loads[destination] == 1, load
    edges = released_edges(run)
    # the small loop's junctions were taken, told by direction; the big loop's way too
    assert ('JA-C1', 'left') in edges and ('CX-B1', 'right') in edges
    assert ('JA-A4', 'straight') in edges or ('L1-B1', None) in edges


def test_a_truck_behind_one_off_the_broker_is_re_routed_round_the_other_loop(dispatched):
    """agv2 stands at C1.1, off the broker: the crossover is closed, and nobody can open it.

    agv1 carries a load from A2 to B2. The shorter way crosses at JA; agv1 waits at A3.1, its
    decision point, for C1, which agv2 holds. After the watchdog's patience the dispatcher
    plans the rest anew round the big loop and releases it by an order update.
    """
    fleet, dispatcher, run = dispatched({'agv1': 'A1.1', 'agv2': 'C1.1'})
    dispatcher.set_online('agv2', False)
    dispatcher.submit(TransportOrder('t1', 'A2', 'B2'))
    assert run.run(300.0, until=lambda: bool(dispatcher.done or dispatcher.failed
                                             or fleet.collisions)), run.summary()
    assert (dispatcher.done, dispatcher.failed, fleet.collisions) == (['t1'], [], [])
    [(truck, order_id, avoided, waited)] = dispatcher.reroutes
    assert (truck, order_id, avoided) == ('agv1', 't1', ['C1'])
    assert REROUTE_AFTER <= waited < REROUTE_AFTER + 0.2
    sent = [m for _, name, topic, m in run.sent if topic == 'order' and name == 'agv1']
    first = [(n.node_id, n.released) for n in sent[0].nodes]
    assert first[4:7] == [('A3.1', True), ('JA', False), ('C1', False)]  # its horizon: across
    assert (sent[1].order_update_id, [n.node_id for n in sent[1].nodes if n.released]) == (
        1, ['A3.1', 'JA', 'A4', 'A4.1', 'A5', 'A5.1', 'L1', 'B1', 'B1.1', 'B2', 'B2.1'])
    assert ('JA-A4', 'straight') in released_edges(run)
    assert fleet.station_loads['B2'] == 1
    assert not any('queued' in r for r in fleet.reports('agv2'))  # sent nothing while away


def test_ten_trucks_deadlocked_on_the_small_loop_are_freed_by_re_routing_one(dispatched):
    """Ten trucks stand at the ten stop markers round the small loop; one gets a load to move.

    agv1 at A3.1 is to fetch a load from A1 (the shorter way across, through C1). Each truck
    in front of the next is asked to make way, and none can: every block of the small loop is
    held, a cycle of ten the watchdog reports. After its patience the dispatcher re-routes
    agv1, the one with work, round the big loop, whose blocks are free: the cycle is gone.
    The others are off the broker until agv1 has its job, so that it is the one given it.
    """
    places = ['A3.1', 'A1.1', 'A2.1', 'C1.1', 'B1.1', 'B2.1', 'B3.1', 'B4.1', 'B5.1', 'W3.1']
    fleet, dispatcher, run = dispatched({f'agv{k + 1}': p for k, p in enumerate(places)})
    for name in fleet.names[1:]:
        dispatcher.set_online(name, False)
    dispatcher.submit(TransportOrder('t1', 'A1', 'A5'))
    assert run.run(3.0, until=lambda: 't1' in dispatcher.assignments)
    assert dispatcher.assignments == {'t1': 'agv1'}
    for name in fleet.names[1:]:
        dispatcher.set_online(name, True)
    cycles: list[list[str]] = []

    def moved() -> bool:
        cycles.extend(c for c in dispatcher.deadlocks if c not in cycles)
        return run.states['agv1'].last_node_id in ('A4', 'A4.1') or bool(fleet.collisions)

    assert run.run(60.0, until=moved), run.summary()
    assert [sorted(c) for c in cycles] == [sorted(fleet.names)]  # the one cycle, all ten
    [(truck, order_id, avoided, waited)] = dispatcher.reroutes
    assert (truck, order_id, avoided) == ('agv1', 't1', ['C1'])
    assert REROUTE_AFTER <= waited < REROUTE_AFTER + 0.2
    run.run(5.0)
    assert dispatcher.deadlocks == [] and fleet.collisions == [] and dispatcher.failed == []
