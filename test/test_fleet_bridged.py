"""Trucks in lock step driven through their VDA 5050 bridge cores by a master (no MQTT, no DDS).

The master here is a script: it sends each truck one order when the truck first reports, and
the test reads what the trucks answer. Without traffic control two trucks sent to one stop
collide, and the master hears it as each truck's failed task. With the dispatcher as master,
trucks set down at stop markers and told so by initPosition (which sends the truck the `at`
task) run transfers without a collision: two, and three with one set down at W1.1, which
leaves by L1's SRM; four fill demo_1983's four blocks, and the watchdog reports the deadlock.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from itertools import pairwise
from typing import Any

import pytest

from agv_nodes.fleet.bridged import BridgedFleet
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.harness import Harness
from agv_nodes.vda5050 import VERSION
from agv_nodes.vda5050.common import Action, BlockingType, now
from agv_nodes.vda5050.order import Edge, Node, Order
from agv_nodes.vda5050.state import State

pytestmark = pytest.mark.timeout(300)


def order(truck: str, order_id: str, ids: list[str], actions: dict[str, str]) -> Order:
    nodes = [Node(node_id=n, sequence_id=2 * i, released=True,
                  actions=[Action(action_type=actions[n], action_id=f'{actions[n]}-{n}',
                                  blocking_type=BlockingType.HARD)] if n in actions else [])
             for i, n in enumerate(ids)]
    edges = [Edge(edge_id=f'{a}-{b}', sequence_id=2 * i + 1, released=True, start_node_id=a,
                  end_node_id=b, actions=[]) for i, (a, b) in enumerate(pairwise(ids))]
    return Order(header_id=0, timestamp=now(), version=VERSION, manufacturer='agv_nodes',
                 serial_number=truck, order_id=order_id, order_update_id=0, nodes=nodes,
                 edges=edges)


class ScriptedMaster:
    """Sends each truck its one order at its first state; keeps every state."""

    def __init__(self, orders: dict[str, Order]) -> None:
        self.orders = dict(orders)
        self.states: dict[str, list[State]] = {}

    def on_state(self, truck: str, state: State, now: float) -> None:
        self.states.setdefault(truck, []).append(state)

    def step(self, now: float) -> list[tuple[str, str, Order]]:
        ready = [t for t in self.orders if t in self.states]
        return [(t, 'order', self.orders.pop(t)) for t in ready]


@pytest.fixture
def closing() -> Iterator[Callable[[Fleet], None]]:
    """Return a function that has a fleet closed (its processes ended) after the test."""
    fleets: list[Fleet] = []
    yield fleets.append
    for fleet in fleets:
        fleet.close()


def _events(h: Harness) -> list[dict]:
    return h.events


def _finished(state: State | None) -> bool:
    return state is not None and bool(state.action_states) and all(
        a.action_status == 'FINISHED' for a in state.action_states)


def test_a_master_s_order_runs_on_a_truck_of_the_fleet_through_its_bridge():
    fleet = Fleet('demo_1983', [('A', 4.0)])
    master = ScriptedMaster({'agv1': order('agv1', 'o1', ['L0', 'W0.1', 'L2', 'W2.1'],
                                           {'W0.1': 'pick', 'W2.1': 'drop'})})
    run = BridgedFleet(fleet, master)
    assert run.run(150.0, until=lambda: _finished(run.states.get('agv1')))
    last = run.states['agv1']
    assert (last.order_id, last.last_node_id, last.node_states) == ('o1', 'W2.1', [])
    assert fleet.station_loads['W0'] == 0 and fleet.station_loads['W2'] == 1
    moved = [e for e in fleet.trucks['agv1'].events if e['event'] == 'load_moved']
    assert len(moved) == 2


def test_without_traffic_control_the_master_hears_the_collision_as_failed_tasks():
    fleet = Fleet('demo_1983', [('A', 4.0), ('A', 1.0)])
    way = ['L0', 'W0.1', 'L2', 'W2.1']
    master = ScriptedMaster({t: order(t, f'o-{t}', way, {'W2.1': 'drop'}) for t in fleet.names})
    run = BridgedFleet(fleet, master)
    failed = run.run(120.0, until=lambda: all(
        any(e.error_type == 'taskFailed' for e in run.states[t].errors) for t in fleet.names))
    assert failed, run.summary()
    assert len(fleet.collisions) == 1
    for name in fleet.names:
        (error,) = [e for e in run.states[name].errors if e.error_type == 'taskFailed']
        assert 'collision' in (error.error_description or ''), error
        assert not run.states[name].driving


def test_the_dispatcher_runs_two_trucks_through_three_transfers_without_a_collision():
    """The central computer as the fleet's VDA 5050 master, traffic control by blocks."""
    from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
    from agv_nodes.fleet.track_graph import track_graph
    from agv_nodes.world.layout import layout_path, load_layout

    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    positions = {'agv1': 'W2.2', 'agv2': 'W0.1'}  # set down at stop markers, told by initPosition
    fleet = Fleet('demo_1983', [at[positions[name]] for name in ('agv1', 'agv2')])
    graph = track_graph(lay)
    dispatcher = Dispatcher(graph, fleet.names, positions=positions)
    for i, (source, destination) in enumerate((('W0', 'W2'), ('W1', 'W3'), ('W2', 'W0'))):
        dispatcher.submit(TransportOrder(f't{i + 1}', source, destination))
    seen: list[tuple[str, State]] = []
    record = dispatcher.on_state

    def on_state(truck: str, state: State, now: float) -> None:
        seen.append((truck, state))
        record(truck, state, now)

    dispatcher.on_state = on_state  # every state the trucks sent, for the checks below
    run = BridgedFleet(fleet, dispatcher, graph=graph)
    finished = run.run(600.0, until=lambda: len(dispatcher.done) + len(dispatcher.failed) == 3)
    assert finished, run.summary()
    assert sorted(dispatcher.done) == ['t1', 't2', 't3'] and dispatcher.failed == []
    assert fleet.collisions == [] and dispatcher.conflicts == [] and dispatcher.deadlocks == []
    # every order and update the dispatcher sent was accepted: no truck ever reported an error
    assert not [(t, e.error_type) for t, s in seen for e in s.errors]
    # W0's load went to W2 and W2's to W0; W1's to W3
    assert fleet.station_loads == {'W0': 1, 'W1': 0, 'W2': 0, 'W3': 1}
    moved = sum(e['event'] == 'load_moved' for h in fleet.trucks.values() for e in h.events)
    assert moved == 6


def _dispatched(positions: dict[str, str], processes: int = 1
                ) -> tuple[Fleet, Any, BridgedFleet, list]:
    """Trucks set down at `positions` (told by initPosition), the dispatcher as their master.

    `processes`: 2 steps the trucks in two processes, which run as one does
    (test_fleet_processes.py).
    """
    from agv_nodes.fleet.dispatcher import Dispatcher
    from agv_nodes.fleet.track_graph import track_graph
    from agv_nodes.world.layout import layout_path, load_layout

    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    fleet = Fleet('demo_1983', [at[node] for node in positions.values()], names=list(positions),
                  processes=processes)
    graph = track_graph(lay)
    dispatcher = Dispatcher(graph, fleet.names, positions=positions)
    seen: list[tuple[str, State]] = []
    record = dispatcher.on_state

    def on_state(truck: str, state: State, now: float) -> None:
        seen.append((truck, state))
        record(truck, state, now)

    dispatcher.on_state = on_state  # every state the trucks sent, for the checks
    return fleet, dispatcher, BridgedFleet(fleet, dispatcher, graph=graph), seen


@pytest.mark.timeout(900)
def test_the_dispatcher_runs_three_trucks_one_set_down_at_w1_1_through_four_transfers(closing):
    """Three trucks, one at W1.1: told by initPosition (the `at` task), it leaves by L1's SRM.

    Loads A (W0 -> W2 -> W0) and B (W1 -> W3 -> W1): a load's way back is submitted once its
    way there is done, so each transfer finds its load.
    """
    from agv_nodes.fleet.dispatcher import TransportOrder

    positions = {'agv1': 'W2.2', 'agv2': 'W0.1', 'agv3': 'W1.1'}
    fleet, dispatcher, run, seen = _dispatched(positions, processes=2)
    closing(fleet)
    back = {'t1': ('t3', 'W2', 'W0'), 't2': ('t4', 'W3', 'W1')}
    dispatcher.submit(TransportOrder('t1', 'W0', 'W2'))
    dispatcher.submit(TransportOrder('t2', 'W1', 'W3'))

    def over() -> bool:
        for done in [t for t in back if t in dispatcher.done]:
            dispatcher.submit(TransportOrder(*back.pop(done)))
        return len(dispatcher.done) + len(dispatcher.failed) == 4 or bool(fleet.collisions)

    assert run.run(900.0, until=over), run.summary()
    assert sorted(dispatcher.done) == ['t1', 't2', 't3', 't4'] and dispatcher.failed == []
    assert fleet.collisions == [] and dispatcher.conflicts == [] and dispatcher.deadlocks == []
    assert not [(t, e.error_type) for t, s in seen for e in s.errors]
    # every truck was told where it stands, and took it
    for name, node in positions.items():
        n = node[1]
        told = [r for r in fleet.reports(name) if r.startswith("task 1 'at ")]
        assert told and told[-1].endswith(f'completed [last marker L{n}]'), told
    # both loads went there and back
    assert fleet.station_loads == {'W0': 1, 'W1': 1, 'W2': 0, 'W3': 0}
    moved = sum(e['event'] == 'load_moved' for name in fleet.names
                for e in fleet.query(name, _events))
    assert moved == 8


def test_a_fourth_truck_at_w3_1_fills_every_block_and_the_watchdog_reports_the_deadlock():
    """demo_1983 has four blocks; four trucks hold all of them and none can enter the next.

    Traffic control admits one truck a block (docs/fleet.md), and on the one-way loop every
    way out of a block is into the next: with every block held, nothing can move. The trucks
    stand still, told where they are, and the dispatcher's watchdog names the cycle.
    """
    from agv_nodes.fleet.dispatcher import TransportOrder
    from agv_nodes.fleet.reroute import REROUTE_AFTER

    positions = {'agv1': 'W2.2', 'agv2': 'W0.1', 'agv3': 'W1.1', 'agv4': 'W3.1'}
    fleet, dispatcher, run, _seen = _dispatched(positions)
    dispatcher.submit(TransportOrder('t1', 'W0', 'W2'))
    assert run.run(20.0, until=lambda: bool(dispatcher.deadlocks)), run.summary()
    run.run(REROUTE_AFTER + 2.0)  # past the watchdog's patience
    (cycle,) = dispatcher.deadlocks
    assert sorted(cycle) == sorted(positions)
    assert fleet.collisions == [] and dispatcher.done == []
    assert dispatcher.reroutes == []  # its patience is over, but a one-way loop has no other way
    for name, node in positions.items():
        assert run.states[name].last_node_id == node and not run.states[name].driving
        assert any(r.startswith("task 1 'at ") and 'completed' in r for r in fleet.reports(name))


def test_the_dispatcher_runs_four_trucks_on_the_house_numbered_floor(closing):
    """fleet_1983 repeats identities 0 and 2 along its streets (Baker 1983, 8.5).

    Four trucks parked a block apart each carry a load from Ak to Bk, half way round the loop:
    every order spans houses of one identity, which the bridges drive by `pass` tasks.
    """
    from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
    from agv_nodes.fleet.track_graph import track_graph
    from agv_nodes.world.fleet_floor import programme_loads
    from agv_nodes.world.layout import layout_path, load_layout

    lay = load_layout(layout_path('fleet_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    positions = {f'agv{k + 1}': place for k, place in enumerate(lay.parking[:4])}
    fleet = Fleet('fleet_1983', [at[p] for p in positions.values()], names=list(positions),
                  processes=2)
    closing(fleet)
    graph = track_graph(lay)
    dispatcher = Dispatcher(graph, fleet.names, positions=positions, parking=positions)
    for load, (source, destination) in programme_loads(lay.stations, 4).items():
        dispatcher.submit(TransportOrder(load, source, destination))
    run = BridgedFleet(fleet, dispatcher, graph=graph)
    assert run.run(600.0, until=lambda: len(dispatcher.done) == 4
                   or bool(dispatcher.failed or fleet.collisions)), run.summary()
    assert sorted(dispatcher.done) == ['load1', 'load2', 'load3', 'load4']
    assert (dispatcher.failed, fleet.collisions, dispatcher.deadlocks) == ([], [], [])
    for load, (_, destination) in programme_loads(lay.stations, 4).items():
        assert fleet.station_loads[destination] == 1, load
    spans = [[graph.nodes[n.node_id].location for n in message.nodes
              if n.released and graph.nodes[n.node_id].kind == 'location']
             for _, _, topic, message in run.sent if topic == 'order']
    assert any(len(ids) > len(set(ids)) for ids in spans)  # a base past a repeated identity
