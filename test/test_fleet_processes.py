"""A lock-step fleet stepped in two processes runs the very samples one process runs.

agv_nodes.fleet.truck_processes forks processes that step some of the trucks, in lock step with
the first. The same seeded runs in one process and in two must end bit for bit alike: the
dispatcher's transfers and every message it sent, each truck's events, notes and pose, the
stations' loads and the collisions. The things that cross between the processes are each
exercised: a task for a far truck, a bump where bodies touch, a load one truck takes that is
gone for a truck of the other process.
"""

from __future__ import annotations

from typing import Any

import pytest

from agv_nodes.fleet.bridged import BridgedFleet
from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.lockstep import Fleet, shares
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.fleet.truck_processes import load_changes, merge_load_changes
from agv_nodes.harness import Harness
from agv_nodes.world.fleet_floor import programme_loads
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(300)


def _trace(h: Harness) -> tuple:
    """Return what a truck did (run in the process that steps it: picklable)."""
    return (h.now, h.world.pose(), h.events, h.world.events,
            [(n.time, n.text) for n in h.cores['communications'].notes.recent])


def _fail(h: Harness) -> None:
    raise ZeroDivisionError('on purpose')


def _body(message: Any) -> dict:
    return message.model_dump(exclude={'timestamp'})  # the header's wall-clock time


def _dispatched(processes: int, seconds: float) -> dict[str, Any]:
    """Four trucks on fleet_1983 under the dispatcher, as bench/fleet_bench.py runs them."""
    lay = load_layout(layout_path('fleet_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    positions = {f'agv{k + 1}': place for k, place in enumerate(lay.parking[:4])}
    graph = track_graph(lay)
    with Fleet('fleet_1983', [at[p] for p in positions.values()], names=list(positions),
               processes=processes) as fleet:
        dispatcher = Dispatcher(graph, fleet.names, positions=positions, parking=positions)
        for load, (source, destination) in programme_loads(lay.stations, 4).items():
            dispatcher.submit(TransportOrder(load, source, destination))
        run = BridgedFleet(fleet, dispatcher, graph=graph)
        run.run(seconds)
        return {'done': list(dispatcher.done), 'failed': list(dispatcher.failed),
                'sent': [(t, truck, topic, _body(m)) for t, truck, topic, m in run.sent],
                'states': {name: _body(s) for name, s in run.states.items()},
                'trucks': {name: fleet.query(name, _trace) for name in fleet.names},
                'loads': dict(fleet.station_loads), 'collisions': list(fleet.collisions),
                'local': list(fleet.trucks)}


def test_four_dispatched_trucks_in_two_processes_run_as_in_one():
    one, two = _dispatched(1, 240.0), _dispatched(2, 240.0)
    assert one['local'] == ['agv1', 'agv2', 'agv3', 'agv4'] and two['local'] == ['agv1', 'agv2']
    assert one['done'] and not one['failed']  # loads moved: tasks went to trucks of both
    assert {truck for _t, truck, topic, _m in one['sent'] if topic == 'order'} == \
        {'agv1', 'agv2', 'agv3', 'agv4'}
    assert sum(e['event'] == 'load_moved' for t in one['trucks'].values() for e in t[2]) >= 2
    for key in ('done', 'failed', 'sent', 'states', 'loads', 'collisions'):
        assert one[key] == two[key], key
    for name in one['trucks']:
        assert one['trucks'][name] == two['trucks'][name], name  # bit for bit: floats equal


def _collided(processes: int) -> tuple:
    with Fleet('demo_1983', [('A', 4.0), ('A', 1.0)], processes=processes) as fleet:
        for name in fleet.names:
            fleet.submit(name, 'stop at 2 first')
        fleet.run(60.0, until=lambda: bool(fleet.collisions))
        fleet.run(3.0)
        return fleet.collisions, {name: fleet.query(name, _trace) for name in fleet.names}


def test_a_collision_with_a_truck_of_the_other_process_bumps_it_as_in_one():
    (hit_one, one), (hit_two, two) = _collided(1), _collided(2)
    assert len(hit_one) == 1 and hit_one == hit_two
    for name in ('agv1', 'agv2'):
        assert one[name] == two[name], name
        assert [e['time'] for e in two[name][2] if e['event'] == 'collision'] == \
            [hit_two[0].time]
        assert abs(two[name][1][3]) < 0.002  # at rest: the bump cut its drive


@pytest.mark.parametrize('front_first', [True, False], ids=['taken-here', 'taken-there'])
def test_a_load_taken_in_one_process_is_gone_for_a_truck_of_the_other(front_first):
    """The front truck takes W0's only load; the one behind, in the other process, finds none."""
    starts = {'front': ('A', 4.0), 'back': ('A', 1.0)}
    names = ['front', 'back'] if front_first else ['back', 'front']
    with Fleet('demo_1983', [starts[n] for n in names], names=names, processes=2) as fleet:
        assert list(fleet.trucks) == names[:1]  # the other is stepped by the other process
        fleet.submit('front', 'load at 0')
        fleet.submit('front', 'unload at 2')
        assert fleet.run(120.0, until=lambda: sum(
            'completed' in r for r in fleet.reports('front')) == 2), fleet.reports('front')[-3:]
        assert fleet.station_loads == {'W0': 0, 'W1': 1, 'W2': 1, 'W3': 0}
        fleet.submit('back', 'load at 0')
        assert fleet.run(120.0, until=lambda: any(
            'FAILED' in r for r in fleet.reports('back'))), fleet.reports('back')[-3:]
        assert 'load failed' in fleet.reports('back')[-1]
        assert fleet.collisions == []


def test_station_changes_merge_and_two_processes_changing_one_station_stop_the_run():
    assert load_changes({'W0': 1, 'W1': 0}, {'W0': 0, 'W1': 0}) == {'W0': 0}
    assert merge_load_changes([{'W0': 0}, {}, {'W2': 1}], 1.0) == {'W0': 0, 'W2': 1}
    with pytest.raises(RuntimeError, match=r'station W0 changed by trucks of two processes'):
        merge_load_changes([{'W0': 0}, {'W0': 2}], 12.5)


def test_shares_give_the_first_process_the_fewest_trucks():
    assert shares(8, 2) == [4, 4]
    assert shares(7, 2) == [3, 4]
    assert shares(5, 3) == [1, 2, 2]
    assert shares(1, 2) == [1]  # no process without a truck
    with pytest.raises(ValueError, match='processes: 0 must be >= 1'):
        Fleet('demo_1983', [('A', 4.0)], processes=0)


def test_a_failure_in_the_other_process_is_raised_named_and_its_process_ends():
    fleet = Fleet('demo_1983', [('A', 4.0), ('A', 1.0)], processes=2)
    worker = fleet._owner['agv2']
    with pytest.raises(RuntimeError, match=r'(?s)fleet process of agv2 failed:.*on purpose'):
        fleet.query('agv2', _fail)
    fleet.close()
    assert not worker._process.is_alive()
    with pytest.raises(RuntimeError, match='fleet process of agv2 ended'):
        worker.answer()
    with pytest.raises(RuntimeError, match='fleet: closed'):  # never half a fleet stepped
        fleet.step()
