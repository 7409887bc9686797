"""The fleet dispatcher (agv_nodes.fleet.dispatcher) and its blocks on demo_1983, without ROS.

Each truck is faked by the real order flow (agv_nodes.vda5050.order_flow.OrderFlow), which
must accept every order and update the dispatcher sends, and a scripted truck that drives the
tasks the flow hands it along the task language's way (order_tasks.task_way), node by node,
reporting as the truck's report lines would. Trucks move one event at a time, in turn, and
after every event and every dispatcher step the test checks: no two trucks in one block, each
truck's body (1.8 m behind its card reader) and the rest of its task's way in blocks granted
to it, and its released nodes in blocks granted to it.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

import pytest

from agv_nodes.communications.task_language import parse_task
from agv_nodes.fleet.blocks import Block, Reservations, default_blocks
from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.vda5050 import VERSION, common
from agv_nodes.vda5050.order import Order
from agv_nodes.vda5050.order_flow import OrderFlow
from agv_nodes.vda5050.order_tasks import TASK_FAILED
from agv_nodes.vda5050.state import (
    ActionStatus,
    BatteryState,
    EStop,
    OperatingMode,
    SafetyState,
    State,
)
from agv_nodes.vda5050.task_way import task_way
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(120)

LENGTH = 1.8  # m, the truck


@pytest.fixture(scope='module')
def graph() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


class FakeTruck:
    """A truck behind its order flow: it drives its tasks one event at a time."""

    def __init__(self, name: str, graph: TrackGraph, start: str = '') -> None:
        self.name, self.graph, self.flow = name, graph, OrderFlow(graph)
        self.node: str | None = start or None  # the last node the truck's reader was at
        self.next: str | None = None if start else graph.start  # driving the edge to it
        self.history = [start] if start else []  # the nodes it has been at, in order
        self.flow.last_node_id = start
        self.marker: int | None = None  # the last location marker reported
        self.queued: deque[tuple[int, str]] = deque()  # (task id, text), not yet started
        self.task: dict | None = None  # the one it is doing
        self.task_id = 0
        self.fail_next = ('', '')  # cause, 'start' | 'act': how the next task is to fail
        self.orders: list[Order] = []

    def state(self) -> State:
        return State(header_id=0, timestamp=common.now(), version=VERSION,
                     manufacturer='agv_nodes', serial_number=self.name,
                     battery_state=BatteryState(battery_charge=100, charging=False),
                     operating_mode=OperatingMode.AUTOMATIC,
                     safety_state=SafetyState(e_stop=EStop.NONE, field_violation=False),
                     **self.flow.state_fields())

    def take(self, order: Order) -> None:
        out = self.flow.on_order(order)
        assert out.verdict in ('accepted', 'updated'), (order, out.errors, self.flow.errors)
        self.orders.append(order)
        self.queue(out.tasks)

    def queue(self, texts: list[str]) -> None:
        for text in texts:
            self.task_id += 1
            self.flow.task_queued(self.task_id, text)
            if text == 'abort':  # the truck drops its queue and stops where it is
                self.queued.clear()
                self.task = None
                self.flow.task_state(self.task_id, 'completed', 0, '', self.marker)
            else:
                self.queued.append((self.task_id, text))

    def report(self, state: str, step: int = 0, cause: str = '') -> None:
        out = self.flow.task_state(self.task['id'], state, step, cause, self.marker)
        self.queue(out.tasks)

    def event(self) -> bool:
        """Do the next thing the truck does; False when it has nothing to do."""
        task = self.task
        if task is None:
            if not self.queued:
                return False
            task_id, text = self.queued.popleft()
            parsed = parse_task(text)  # the truck would refuse a text it cannot parse
            stop = next(n.id for n in self.graph.nodes.values() if n.stoppable
                        and n.location == parsed.location
                        and n.conveyor == ('first', 'second').index(parsed.marker))
            way = task_way(self.graph, self.node or self.graph.start, self.node is not None,
                           stop)
            self.task = {'id': task_id, 'way': way, 'at': 0 if self.node else -1,
                         'steps': 1 if parsed.op == 'stop' else 2, 'phase': 'drive'}
            if self.fail_next[1] == 'start':
                self.fail('FAILED', 0)
            else:
                self.report('running')
            return True
        if task['phase'] == 'drive':
            if self.next is None:  # depart on the next edge of the way
                self.next = task['way'][task['at'] + 1]
                return True
            self.node, self.next = self.next, None
            self.history.append(self.node)
            task['at'] += 1
            here = self.graph.nodes[self.node]
            if here.kind == 'location':
                self.marker = here.location
            if task['at'] == len(task['way']) - 1:
                self.report('step done')
                task['phase'] = 'act' if task['steps'] == 2 else 'end'
            elif here.kind == 'location':
                self.report('running')
            return True
        if task['phase'] == 'act':
            if self.fail_next[1] == 'act':
                self.fail('FAILED', 1)
                return True
            self.report('running', 1)
            task['phase'] = 'end'
            return True
        self.report('completed')
        self.task = None
        return True

    def idle(self) -> bool:
        return self.task is None and not self.queued

    def fail(self, state: str, step: int) -> None:
        cause, self.fail_next = self.fail_next[0], ('', '')
        self.report(state, step, cause)
        self.task = None

    def body(self, blocks: Reservations, length: float = LENGTH) -> set[str]:
        """Return the blocks the truck's body may be in: from its reader back `length`."""
        if self.node is None:
            return {blocks.block_of(self.next)}
        out = {blocks.block_of(self.node)}
        if self.next is not None:
            out.add(blocks.block_of(self.next))
        behind = 0.0
        for later, earlier in zip(reversed(self.history), list(reversed(self.history))[1:],
                                  strict=False):
            out.add(blocks.block_of(later))
            behind += self.graph.edge(earlier, later).length
            if behind >= length:
                break
            out.add(blocks.block_of(earlier))
        return out

    def ahead(self) -> list[str]:
        """Return the nodes the truck is yet to drive through on its current task."""
        if self.task is None or self.task['phase'] != 'drive':
            return []
        return self.task['way'][self.task['at'] + 1:]


class Floor:
    """A dispatcher and its fake trucks, moved one event at a time and checked throughout."""

    def __init__(self, graph: TrackGraph, starts: dict[str, str], length: float = LENGTH,
                 quiet: bool = True, **kw: object) -> None:
        self.graph, self.length, self.quiet = graph, length, quiet
        self.trucks = {n: FakeTruck(n, graph, s) for n, s in starts.items()}
        self.dispatcher = Dispatcher(graph, sorted(starts), truck_length=length, **kw)
        self.blocks = self.dispatcher.reservations
        self.headers: dict[tuple[str, str], int] = {}
        self.now = 0.0
        self.events = 0
        for name in self.trucks:
            self.feed(name)
        self.step()

    def feed(self, name: str) -> None:
        self.dispatcher.on_state(name, self.trucks[name].state(), self.now)

    def step(self) -> None:
        for _ in range(10):
            messages = self.dispatcher.step(self.now)
            self.check()
            if not messages:
                return
            for name, topic, msg in messages:
                assert topic == 'order' and isinstance(msg, Order)
                assert msg.header_id == self.headers.get((name, topic), 0)
                self.headers[name, topic] = msg.header_id + 1
                assert msg.serial_number == name and msg.version == VERSION
                self.trucks[name].take(msg)
                self.feed(name)
            self.check()
        raise AssertionError('the dispatcher keeps sending')

    def check(self) -> None:
        """Check the safety property: no two trucks in a block, none outside its grants."""
        where: dict[str, str] = {}
        for name, truck in self.trucks.items():
            granted = self.dispatcher.granted(name)
            body = truck.body(self.blocks, self.length)
            assert body <= granted, (name, body, granted, self.events)
            ahead = set(self.blocks.blocks_of(truck.ahead()))
            assert ahead <= granted, (name, truck.ahead(), granted)
            released = [n.node_id for n in truck.flow.state_fields()['node_states']
                        if n.released]
            assert set(self.blocks.blocks_of(released)) <= granted, (name, released, granted)
            for block in body:
                assert block not in where, (block, name, where[block])
                where[block] = name
        assert self.dispatcher.deadlocks == [] or not self.quiet
        assert self.dispatcher.conflicts == []

    def round(self) -> bool:
        """Give each truck, in turn, one event; return False when none moved."""
        moved = False
        for name in sorted(self.trucks):
            self.now += 0.5
            if self.trucks[name].event():
                moved, self.events = True, self.events + 1
                self.check()
                self.feed(name)
                self.step()
        if not moved:
            self.step()
        return moved

    def moves(self, rounds: int) -> None:
        for _ in range(rounds):
            self.round()

    def run(self, until: Callable[[], bool], limit: int = 3000) -> None:
        idle = 0
        while not until():
            idle = 0 if self.round() else idle + 1
            assert idle < 5 and self.events < limit, self.status()

    def status(self) -> str:
        d = self.dispatcher
        return (f'done {d.done} failed {d.failed} waits {d.reservations.wait_for()} '
                + ' '.join(f'{n}@{t.node}>{t.next} holds {sorted(d.granted(n))}'
                           for n, t in self.trucks.items()))


# -- blocks --------------------------------------------------------------------------------

def test_default_blocks_are_a_location_and_its_stop_markers(graph):
    blocks = {b.name: set(b.nodes) for b in default_blocks(graph)}
    assert blocks == {'L0': {'L0', 'W0.1'}, 'L2': {'L2', 'W2.1', 'W2.2'}, 'L1': {'L1', 'W1.1'},
                      'L3': {'L3', 'W3.1'}}


def test_grants_are_all_or_nothing_and_exclusive(graph):
    r = Reservations(graph)
    assert r.grant('a', ['L0', 'L2'])
    assert not r.grant('b', ['L1', 'L2'])
    assert r.holder('L1') is None and r.waiting('b') == {'L2'}
    assert r.wait_for() == {'b': {'a'}}
    assert r.release('a', ['L2']) == ['L2']
    assert r.grant('b', ['L1', 'L2']) and r.waiting('b') == set()
    assert r.held('a') == {'L0'} and r.held('b') == {'L1', 'L2'}


def test_the_footprint_keeps_a_block_until_the_truck_is_clear_of_it(graph):
    r = Reservations(graph)
    assert r.footprint(['W0.1', 'L2']) == {'L2'}  # 1.8 m on: the tail is on W0.1-L2
    assert r.footprint(['L0', 'W0.1', 'L2'], 2.0) == {'L0', 'L2'}
    assert r.footprint(['W2.2', 'L1', 'W1.1']) == {'L1'}
    assert r.footprint(['L0']) == {'L0'}


def test_a_wait_cycle_is_reported_as_a_deadlock(graph):
    r = Reservations(graph)
    for truck, block in (('a', 'L0'), ('b', 'L2'), ('c', 'L1')):
        assert r.grant(truck, [block])
    assert not r.grant('a', ['L2']) and not r.grant('b', ['L1'])
    assert r.deadlocks() == []  # a waits for b, b for c: c can go on
    assert not r.grant('c', ['L3', 'L0'])
    assert r.deadlocks() == [['a', 'b', 'c']]
    r.stop_waiting('b')
    assert r.deadlocks() == []
    two = Reservations(graph, [Block('x', frozenset({'L0', 'W0.1', 'L2', 'W2.1', 'W2.2'})),
                               Block('y', frozenset({'L1', 'W1.1', 'L3', 'W3.1'}))])
    assert two.grant('a', ['x']) and two.grant('b', ['y'])
    assert not two.grant('a', ['y']) and not two.grant('b', ['x'])
    assert two.deadlocks() == [['a', 'b']]


def test_blocks_must_cover_each_node_once(graph):
    with pytest.raises(ValueError, match='no block'):
        Reservations(graph, [Block('x', frozenset({'L0'}))])


# -- the dispatcher ------------------------------------------------------------------------

def test_one_truck_takes_a_load_from_w0_to_w2(graph):
    floor = Floor(graph, {'agv1': ''})
    floor.dispatcher.submit(TransportOrder('t1', 'W0', 'W2'))
    floor.step()
    assert floor.dispatcher.assignments == {'t1': 'agv1'}
    order = floor.trucks['agv1'].orders[0]
    assert [n.node_id for n in order.nodes] == ['L0', 'W0.1', 'L2', 'W2.1']
    assert [n.sequence_id for n in order.nodes] == [0, 2, 4, 6]
    assert [e.edge_id for e in order.edges] == ['L0-W0.1', 'W0.1-L2', 'L2-W2.1']
    assert {a.action_type for n in order.nodes for a in n.actions} == {'pick', 'drop'}
    floor.run(lambda: floor.dispatcher.done == ['t1'])
    flow = floor.trucks['agv1'].flow
    assert flow.last_node_id == 'W2.1' and flow.errors == []
    assert {a.action_status for a in flow.state_fields()['action_states']} \
        == {ActionStatus.FINISHED}
    assert floor.dispatcher.granted('agv1') == {'L2'}  # only where it stands


def test_two_trucks_two_transfers_the_same_way(graph):
    floor = Floor(graph, {'agv1': 'W3.1', 'agv2': 'W1.1'})
    for i in (1, 2):
        floor.dispatcher.submit(TransportOrder(f't{i}', 'W0', 'W2'))
    floor.run(lambda: len(floor.dispatcher.done) == 2)
    assert sorted(floor.dispatcher.done) == ['t1', 't2']
    assert floor.dispatcher.assignments == {'t1': 'agv1', 't2': 'agv2'}
    assert floor.dispatcher.failed == []
    # agv2 waited for the blocks agv1 held and was released in parts, by updates
    assert any(o.order_update_id > 0 for o in floor.trucks['agv2'].orders)


def test_three_transfers_for_two_trucks_first_come_first_served(graph):
    floor = Floor(graph, {'agv1': 'W3.1', 'agv2': 'W2.2'})
    transports = [TransportOrder('t1', 'W0', 'W2'), TransportOrder('t2', 'W1', 'W3'),
                  TransportOrder('t3', 'W2', 'W0')]
    for t in transports:
        floor.dispatcher.submit(t)
    floor.step()
    assert list(floor.dispatcher.assignments) == ['t1', 't2']
    assert [t.id for t in floor.dispatcher.queue] == ['t3']
    floor.run(lambda: len(floor.dispatcher.done) == 3)
    assert list(floor.dispatcher.assignments) == ['t1', 't2', 't3']
    assert sorted(floor.dispatcher.done) == ['t1', 't2', 't3']


def test_the_nearest_idle_truck_is_chosen(graph):
    floor = Floor(graph, {'a': 'W1.1', 'b': 'W3.1', 'c': 'W2.1'})
    floor.dispatcher.submit(TransportOrder('t1', 'W0', 'W2'))
    floor.step()
    assert floor.dispatcher.assignments == {'t1': 'b'}  # 6.1 m from W0.1; c 36 m, a 28 m
    floor.dispatcher.submit(TransportOrder('t2', 'W1', 'W3'))
    floor.step()
    assert floor.dispatcher.assignments['t2'] == 'c'  # W2.1 to W1.1: 13 m; a: a lap
    floor.run(lambda: len(floor.dispatcher.done) == 2)


def test_a_failed_action_alone_is_told_in_the_truck_s_words(graph):
    """A FAILED action of the order, with no taskFailed error: its resultDescription is why."""
    floor = Floor(graph, {'a': 'W1.1', 'b': 'W0.1'})
    truck = floor.trucks['a']
    truck.fail_next = ('load failed (load)', 'act')
    with_errors = truck.state

    def without_task_failed() -> State:
        state = with_errors()
        return state.model_copy(update={'errors': [
            e for e in state.errors if e.error_type != TASK_FAILED]})
    truck.state = without_task_failed
    floor.dispatcher.submit(TransportOrder('t1', 'W3', 'W2'))
    floor.step()
    floor.run(lambda: floor.dispatcher.failed == ['t1'])
    assert not truck.state().errors
    assert 'load failed (load)' in floor.dispatcher.failures['t1']


def test_a_truck_whose_task_failed_gets_no_work_until_its_errors_clear(graph):
    floor = Floor(graph, {'a': 'W1.1', 'b': 'W0.1'})
    floor.trucks['a'].fail_next = ('load failed (load)', 'act')
    floor.dispatcher.submit(TransportOrder('t1', 'W3', 'W2'))
    floor.step()
    assert floor.dispatcher.assignments == {'t1': 'a'}  # 22 m to W3.1; b 37 m
    floor.run(lambda: floor.dispatcher.failed == ['t1'])
    assert floor.dispatcher.done == [] and floor.trucks['a'].node == 'W3.1'
    assert 'load failed (load)' in floor.dispatcher.failures['t1']  # the truck's own words
    assert floor.dispatcher.granted('a') == {'L3'}  # it stands where it failed
    floor.run(lambda: floor.trucks['b'].idle())  # b made way for a's drop: it drives on
    assert floor.trucks['b'].node == 'W2.1'
    floor.dispatcher.submit(TransportOrder('t2', 'W0', 'W1'))
    floor.step()
    assert floor.dispatcher.assignments['t2'] == 'b'  # 41 m, but a (7 m) failed
    floor.moves(60)  # b drives on, but a stands in its way
    assert floor.dispatcher.done == []
    floor.dispatcher.submit(TransportOrder('t3', 'W3', 'W0'))
    floor.step()
    assert 't3' not in floor.dispatcher.assignments
    floor.trucks['a'].flow.errors = []  # the truck was put right
    floor.feed('a')
    floor.step()
    assert floor.dispatcher.assignments['t3'] == 'a'
    floor.run(lambda: floor.dispatcher.done == ['t2', 't3'])


def test_an_idle_truck_goes_to_its_parking_spot_and_back_after_work(graph):
    floor = Floor(graph, {'a': 'W1.1', 'b': 'W0.1'}, parking={'a': 'W3.1'})
    [order] = floor.trucks['a'].orders
    assert (order.order_id, order.order_update_id) == ('park-a-1', 0)
    assert [n.node_id for n in order.nodes] == ['W1.1', 'L3', 'W3.1']
    assert all(n.released and not n.actions for n in order.nodes)
    assert floor.trucks['b'].orders == []  # no parking spot: it stays
    floor.run(lambda: floor.trucks['a'].node == 'W3.1' and floor.trucks['a'].task is None)
    floor.dispatcher.submit(TransportOrder('t1', 'W1', 'W2'))
    floor.run(lambda: floor.dispatcher.done == ['t1'])
    floor.run(lambda: floor.trucks['a'].node == 'W3.1' and floor.trucks['a'].task is None)
    assert floor.trucks['a'].orders[-1].order_id.startswith('park-a')


def test_three_trucks_on_four_blocks_never_deadlock(graph):
    floor = Floor(graph, {'a': 'W0.1', 'b': 'W2.1', 'c': 'W3.1'})
    stations = ['W0', 'W1', 'W2', 'W3']
    for i in range(12):
        source = stations[(i * 3) % 4]
        destination = stations[(i * 3 + 1 + i % 3) % 4]
        floor.dispatcher.submit(TransportOrder(f't{i}', source, destination))
    floor.run(lambda: len(floor.dispatcher.done) == 12, limit=20000)
    assert floor.dispatcher.failed == []
    orders = [o for t in floor.trucks.values() for o in t.orders]
    # the policy at work: idle trucks made way, and stalled ones stood aside at a branch
    assert any(o.order_id.startswith('yield-') for o in orders)
    assert any(base[-1].node_id in ('W1.1', 'W3.1') and not base[-1].actions
               and len(base) < len(o.nodes) and o.order_id.startswith('t')
               for o in orders for base in [[n for n in o.nodes if n.released]])


def test_a_longer_truck_keeps_the_block_behind_it_longer(graph):
    floor = Floor(graph, {'agv1': 'W3.1', 'agv2': 'W1.1'}, length=2.5)
    for i in (1, 2):
        floor.dispatcher.submit(TransportOrder(f't{i}', 'W0', 'W2'))
    at_l2: list[set[str]] = []  # agv1's blocks each time its reader is at L2

    def done() -> bool:
        if floor.trucks['agv1'].node == 'L2':
            at_l2.append(floor.dispatcher.granted('agv1'))
        return len(floor.dispatcher.done) == 2

    floor.run(done)
    # at L2 its tail is still behind W0.1 (1.8 m back): L0 is kept until it is clear of it
    assert at_l2 and all('L0' in held for held in at_l2)
    assert sorted(floor.dispatcher.done) == ['t1', 't2']


def test_as_many_trucks_as_blocks_can_deadlock_and_the_watchdog_says_so(graph):
    floor = Floor(graph, {'a': 'W0.1', 'b': 'W2.1', 'c': 'W1.1', 'd': 'W3.1'}, quiet=False)
    for i, (source, destination) in enumerate([('W0', 'W2'), ('W2', 'W1'), ('W1', 'W3'),
                                               ('W3', 'W0')]):
        floor.dispatcher.submit(TransportOrder(f't{i}', source, destination))
    floor.step()
    assert len(floor.dispatcher.assignments) == 4
    assert all(t.orders == [] for t in floor.trucks.values())  # none has a block to go to
    assert floor.dispatcher.deadlocks == [['a', 'b', 'c', 'd']]
    assert floor.dispatcher.reservations.wait_for() == {'a': {'b'}, 'b': {'c'}, 'c': {'d'},
                                                       'd': {'a'}}


def test_trucks_set_down_at_stop_markers_are_told_where_they_stand(graph):
    """positions: initPosition once per truck; no work before the truck knows where it is."""
    trucks = {n: FakeTruck(n, graph) for n in ('agv1', 'agv2')}
    d = Dispatcher(graph, sorted(trucks), positions={'agv1': 'W2.2', 'agv2': 'W0.1'})
    for name, t in trucks.items():
        d.on_state(name, t.state(), 0.0)
    d.submit(TransportOrder('t1', 'W1', 'W3'))
    out = d.step(0.0)
    assert [(name, topic) for name, topic, _m in out] == [('agv1', 'instantActions'),
                                                          ('agv2', 'instantActions')]
    assert d.assignments == {}  # neither knows where it stands yet
    for name, _topic, message in out:
        (init,) = message.actions
        assert init.action_type == 'initPosition'
        trucks[name].flow.on_instant_actions(message)
        d.on_state(name, trucks[name].state(), 0.1)
    out = d.step(0.1)
    assert d.assignments == {'t1': 'agv1'}  # W2.2 is nearer W1 than W0.1 is
    ((name, topic, order),) = out
    assert (name, topic) == ('agv1', 'order') and order.nodes[0].node_id == 'W2.2'
    trucks['agv1'].take(order)  # the truck accepts it (take asserts so)
    assert not [m for m in d.step(0.2) if m[1] == 'instantActions']  # told once
