"""The dispatcher as VDA 5050 master over MQTT (agv_nodes.fleet.mqtt_master), without ROS.

A real broker (mosquitto, test/mqtt_broker.py), the MqttMaster on a link of its own, and trucks
played by the test: each is a bridge core (agv_nodes.vda5050.bridge.BridgeCore, what the
vda5050_bridge node runs) on an MQTT link of its own with the bridge's last will, but with no
truck behind it: it answers orders and instant actions with the states a bridge sends, and never
drives. A spy link hears every order and instant action the master publishes; each is checked
against the standard's JSON schema (test/data/vda5050_2.1.0), apart from the package's models.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
import json
import queue
import time

from jsonschema.validators import validator_for
from mqtt_broker import require_mosquitto
import pytest
from vda5050_master import SCHEMAS

from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.mqtt_master import MqttMaster, TransportError, parse_transport
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.mqtt.client import LastWill, MqttLink
from agv_nodes.mqtt.mosquitto import Mosquitto
from agv_nodes.vda5050.bridge import BridgeCore, Outbox
from agv_nodes.vda5050.codec import parse, to_json
from agv_nodes.vda5050.connection import ConnectionState
from agv_nodes.vda5050.order import InstantActions, Order
from agv_nodes.vda5050.topics import TOPICS, topic
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.wall_clock
MANUFACTURER = 'agv_nodes'
WAIT_S = 10.0  # an upper bound only: messages take milliseconds


@pytest.fixture(scope='module')
def graph() -> TrackGraph:
    return track_graph(load_layout(layout_path('demo_1983')))


@pytest.fixture
def broker() -> Iterator[Mosquitto]:
    require_mosquitto()
    with Mosquitto() as running:
        yield running


def schema_errors(name: str, payload: bytes) -> list[str]:
    """Return what the standard's JSON schema of topic `name` finds wrong with `payload`."""
    schema = json.loads((SCHEMAS / f'{name}.schema').read_text(encoding='utf-8'))
    return [e.message for e in validator_for(schema)(schema).iter_errors(json.loads(payload))]


class PlayedTruck:
    """A truck as its bridge answers a master, with no truck behind the bridge (see above)."""

    def __init__(self, url: str, graph: TrackGraph, name: str, at: str = '') -> None:
        self.name = name
        self.core = BridgeCore(graph, MANUFACTURER, name)
        self.core.flow.last_node_id = at  # set down here, and it knows it (no initPosition)
        self.topics = {n: topic(MANUFACTURER, name, n) for n in TOPICS}
        self.inbox: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        self.received: dict[str, list[bytes]] = {'order': [], 'instantActions': []}
        will = self.core.connection(ConnectionState.CONNECTIONBROKEN)
        self.link = MqttLink(url, f'played_{name}', LastWill(self.topics['connection'],
                                                             to_json(will), 1, True))
        for n in self.received:
            self.link.subscribe(self.topics[n], TOPICS[n].qos,
                                lambda _t, payload, n=n: self.inbox.put((n, payload)))
        self.link.connect(timeout=WAIT_S)
        self.send(self.core.reconnected(None, time.monotonic()))  # ONLINE and a first state

    def send(self, out: Outbox) -> None:
        for name, message in out.messages:
            self.raw(name, to_json(message))

    def raw(self, name: str, payload: bytes | str) -> None:
        spec = TOPICS[name]
        assert self.link.publish(self.topics[name], payload, spec.qos, spec.retain)

    def pump(self) -> None:
        """Answer what the master sent, as the bridge would; send a held-back state."""
        now = time.monotonic()
        while not self.inbox.empty():
            name, payload = self.inbox.get()
            self.received[name].append(payload)
            self.send(self.core.on_message(name, payload, now))
        self.send(self.core.tick(now))


class Spy:
    """Every order and instant action published on the broker, as (truck, topic, payload)."""

    def __init__(self, url: str) -> None:
        self.messages: list[tuple[str, str, bytes]] = []
        self.link = MqttLink(url, 'spy')
        for name in ('order', 'instantActions'):
            self.link.subscribe(f'uagv/v2/{MANUFACTURER}/+/{name}', 0, self._take)
        self.link.connect(timeout=WAIT_S)

    def _take(self, topic_name: str, payload: bytes) -> None:
        self.messages.append((topic_name.split('/')[3], topic_name.split('/')[4], payload))

    def to(self, truck: str, name: str) -> list[bytes]:
        return [p for t, n, p in list(self.messages) if (t, n) == (truck, name)]


class Floor:
    """The master, its trucks and the spy on one broker; `run` pumps them all."""

    def __init__(self, url: str, graph: TrackGraph, at: dict[str, str],
                 **dispatcher_options: object) -> None:
        self.url, self.graph = url, graph
        self.spy = Spy(url)
        self.link = MqttLink(url, f'{MANUFACTURER}_dispatcher')
        self.link.connect(timeout=WAIT_S)
        self.master = MqttMaster(Dispatcher(graph, sorted(at), **dispatcher_options), self.link)
        self.trucks = {name: PlayedTruck(url, graph, name, node) for name, node in at.items()}
        self.lines: list[str] = []

    def run(self, until: Callable[[], bool], what: str, wall_limit: float = WAIT_S) -> None:
        deadline = time.monotonic() + wall_limit
        while not until():
            assert time.monotonic() < deadline, f'no {what} within {wall_limit:g} s: ' \
                f'{self.lines}, rejected {dict(self.master.rejected)}'
            for truck in self.trucks.values():
                if truck.link.connected:
                    truck.pump()
            self.master.step(time.monotonic())
            self.lines += self.master.progress()
            time.sleep(0.01)

    def settle(self, seconds: float) -> None:
        """Pump for `seconds` of wall time."""
        end = time.monotonic() + seconds
        self.run(lambda: time.monotonic() > end, 'the end', seconds + WAIT_S)

    def close(self) -> None:
        for link in [self.link, self.spy.link, *(t.link for t in self.trucks.values())]:
            link.close()


@pytest.fixture
def floors(broker, graph) -> Iterator[Callable[..., Floor]]:
    made: list[Floor] = []

    def make(at: dict[str, str], **options: object) -> Floor:
        made.append(Floor(broker.url, graph, at, **options))
        return made[-1]

    yield make
    for floor in made:
        floor.close()


# -- over MQTT ---------------------------------------------------------------------------------

@pytest.mark.timeout(60)
def test_init_position_to_each_truck_then_a_transport_to_the_nearest_idle_one(floors):
    floor = floors({'agv1': '', 'agv2': ''}, positions={'agv1': 'W3.1', 'agv2': 'W1.1'})
    floor.run(lambda: all(len(t.received['instantActions']) == 2
                          for t in floor.trucks.values()), 'initPosition at both trucks')
    for name, where in (('agv1', 'W3.1'), ('agv2', 'W1.1')):
        # first a stateRequest (a master that connects asks), then the truck's initPosition
        asked, placed = floor.spy.to(name, 'instantActions')
        assert schema_errors('instantActions', asked) == []
        assert schema_errors('instantActions', placed) == []
        (request,) = parse(InstantActions, asked).actions
        assert request.action_type == 'stateRequest'
        (init,) = parse(InstantActions, placed).actions
        assert init.action_type == 'initPosition'
        assert [(p.key, p.value) for p in init.action_parameters] == [('lastNodeId', where)]
    floor.run(lambda: {t: s.last_node_id for t, s in floor.master.states.items()}
              == {'agv1': 'W3.1', 'agv2': 'W1.1'}, 'both trucks placed')

    assert floor.master.submit('W0 to W2') == 't1: accepted: W0 to W2'
    floor.run(lambda: floor.spy.to('agv1', 'order'), 'an order to agv1')
    (payload,) = floor.spy.to('agv1', 'order')
    assert schema_errors('order', payload) == []
    order = parse(Order, payload)
    # W3.1 is 6.1 m before W0.1; W1.1 is a lap away (28 m)
    assert (order.order_id, order.serial_number) == ('t1', 'agv1')
    assert [n.node_id for n in order.nodes][0] == 'W3.1'
    assert {a.action_type: n.node_id for n in order.nodes for a in n.actions} \
        == {'pick': 'W0.1', 'drop': 'W2.1'}
    floor.run(lambda: floor.master.states['agv1'].order_id == 't1', 'agv1 taking t1')
    assert floor.master.states['agv1'].errors == []  # the bridge core accepted it
    assert 't1: assigned to agv1' in floor.lines
    assert floor.spy.to('agv2', 'order') == []
    assert floor.master.counts()['orders sent'] == 1
    assert sum(floor.master.rejected.values()) == 0


@pytest.mark.timeout(60)
def test_garbage_and_foreign_states_are_rejected_counted_and_never_acted_on(floors):
    floor = floors({'agv1': 'W3.1'})
    truck = floor.trucks['agv1']
    floor.run(lambda: 'agv1' in floor.master.states and any(
        a.action_type == 'stateRequest' for a in floor.master.states['agv1'].action_states),
        "the answer to the master's stateRequest")
    good = floor.master.states['agv1']
    impostor = truck.core.state().model_copy(update={'serial_number': 'agv9',
                                                     'last_node_id': 'W1.1'})
    lost = truck.core.state().model_copy(update={'last_node_id': 'X9'})
    bad = [('state', b'{not json', 'invalid'),
           ('state', json.dumps({'headerId': 1, 'orderId': 'x'}), 'invalid'),
           ('state', to_json(impostor), 'foreign'),
           ('state', to_json(lost), 'unknown node'),
           ('connection', b'OFFLINE', 'invalid')]
    for i, (name, payload, reason) in enumerate(bad, start=1):
        truck.raw(name, payload)
        floor.run(lambda i=i: sum(floor.master.rejected.values()) == i, f'rejection {i}')
        assert floor.master.rejected[reason] >= 1 and floor.master.rejecting
        assert reason in floor.master.last_rejection
    assert floor.master.rejected == {'invalid': 3, 'foreign': 1, 'unknown node': 1}
    assert floor.master.states['agv1'] is good  # none was taken
    assert floor.master.online('agv1')  # the garbage 'OFFLINE' was not read as OFFLINE
    # not acted on: the truck is where its own state said, not at the impostor's W1.1
    assert floor.master.submit('W1 to W2').startswith('t1: accepted')
    floor.run(lambda: floor.spy.to('agv1', 'order'), 'an order to agv1')
    assert parse(Order, floor.spy.to('agv1', 'order')[0]).nodes[0].node_id == 'W3.1'
    floor.run(lambda: floor.master.states['agv1'].order_id == 't1', 'agv1 taking t1')
    assert not floor.master.rejecting  # a good state since
    assert floor.master.counts()['messages rejected'] == 5


@pytest.mark.timeout(60)
@pytest.mark.parametrize('how', ['CONNECTIONBROKEN', 'OFFLINE'])
def test_a_truck_off_the_broker_gets_no_work_until_it_is_back(floors, how):
    floor = floors({'agv1': 'W3.1', 'agv2': 'W2.2'})
    floor.run(lambda: len(floor.master.states) == 2, 'both trucks reporting')
    gone = floor.trucks['agv2']
    if how == 'OFFLINE':  # a bridge stopping cleanly says so, then disconnects
        gone.send(Outbox(messages=[('connection',
                                    gone.core.connection(ConnectionState.OFFLINE))]))
        gone.link.close(clean=True)
    else:  # the connection lost: the broker publishes the bridge's last will
        gone.link.close(clean=False)
    floor.run(lambda: floor.master.connection.get('agv2') == how, f'agv2 {how}')
    assert not floor.master.online('agv2') and floor.master.counts()['trucks online'] == 1

    # agv2 stands just before W1 (W2.2), yet the transport from W1 goes to agv1, a lap away
    floor.master.submit('W1 to W3')
    floor.run(lambda: floor.spy.to('agv1', 'order'), 'an order to agv1')
    assert parse(Order, floor.spy.to('agv1', 'order')[0]).order_id == 't1'
    floor.master.submit('W1 to W0')  # agv1 is busy: it waits, and agv2 gets nothing
    floor.run(lambda: 't2: queued: no idle truck can take it yet' in floor.lines, 't2 queued')
    floor.settle(0.5)  # what does not come is waited for this long
    assert floor.spy.to('agv2', 'order') == [] and 't2' not in floor.master.dispatcher.assignments

    back = PlayedTruck(floor.url, floor.graph, 'agv2', 'W2.2')  # the bridge reconnects
    floor.trucks['agv2'] = back
    floor.run(lambda: floor.spy.to('agv2', 'order'), 'an order to agv2 once it is back')
    assert parse(Order, floor.spy.to('agv2', 'order')[0]).order_id == 't2'
    assert 't2: assigned to agv2' in floor.lines


# -- the parts without a broker ----------------------------------------------------------------

@pytest.mark.timeout(30)
@pytest.mark.parametrize('text, words', [
    ('', 'empty'),
    ('W0 W2', 'expected'),
    ('from W0 to W2 now', 'expected'),
    ('W9 to W2', "unknown station 'W9' (stations: W0, W1, W2, W3)"),
    ('W0 to W0', 'both W0'),
    ('park-1: W0 to W2', "the dispatcher's own"),
    ('a/b: W0 to W2', "id 'a/b'"),
])
def test_a_bad_transport_text_says_what_is_wrong(text, words):
    with pytest.raises(TransportError, match=words.replace('(', r'\(').replace(')', r'\)')):
        parse_transport(text, ['W0', 'W1', 'W2', 'W3'], 't1')


@pytest.mark.timeout(30)
def test_transport_syntax():
    stations = ['W0', 'W1', 'W2', 'W3']
    assert parse_transport('W0 to W2', stations, 't4') == TransportOrder('t4', 'W0', 'W2')
    assert parse_transport(' job7 : W1 TO W3 ', stations, 't4') \
        == TransportOrder('job7', 'W1', 'W3')


@pytest.mark.timeout(30)
def test_submitted_ids_are_unique_and_the_generated_ones_skip_taken_ones(graph):
    master = MqttMaster(Dispatcher(graph, ['agv1']), MqttLink('mqtt://127.0.0.1:1', 'unused'))
    assert master.submit('t2: W0 to W2') == 't2: accepted: W0 to W2'
    assert master.submit('W0 to W2') == 't1: accepted: W0 to W2'
    assert master.submit('W1 to W2') == 't3: accepted: W1 to W2'  # t2 is the client's
    assert master.submit('t1: W1 to W2') == "rejected 't1: W1 to W2': id 't1' is taken already"
    assert master.transports_rejected == 1 and len(master.dispatcher.queue) == 3
    # no truck has reported: all three wait, and say so once
    assert master.step(0.0) == []  # the link is not connected: nothing is stepped
    assert master.progress() == [f'{t}: queued: no idle truck can take it yet'
                                 for t in ('t2', 't1', 't3')]
    assert master.progress() == []


@pytest.mark.timeout(30)
def test_each_transport_is_reported_step_by_step_and_none_skipped(graph):
    """The report lines follow the dispatcher's lists (set here by hand: no truck drives)."""
    master = MqttMaster(Dispatcher(graph, ['agv1', 'agv2']),
                        MqttLink('mqtt://127.0.0.1:1', 'unused'))
    for text in ('W0 to W2', 'W1 to W3', 'W2 to W0'):
        master.submit(text)
    d = master.dispatcher
    d.queue.popleft()
    d.assignments['t1'] = 'agv1'  # taken at once: never queued
    assert master.progress() == ['t1: assigned to agv1', 't2: queued: no idle truck can take it '
                                 'yet', 't3: queued: no idle truck can take it yet']
    d.queue.clear()
    d.assignments.update(t2='agv2', t3='agv1')
    d.done.append('t1')
    d.failed.append('t2')  # assigned and failed between two calls: both said, in order
    assert master.progress() == ['t1: done (agv1)', 't2: assigned to agv2', 't2: failed (agv2)',
                                 't3: assigned to agv1']
    d.done.append('t3')
    assert master.progress() == ['t3: done (agv1)']
    assert master.progress() == []


def _placed(graph: TrackGraph, name: str, at: str):
    core = BridgeCore(graph, MANUFACTURER, name)
    core.flow.last_node_id = at
    return core.state()


@pytest.mark.timeout(30)
def test_the_dispatcher_sends_a_truck_off_the_broker_nothing(graph):
    """Dispatcher.set_online: no work, and no initPosition, until the truck is back."""
    d = Dispatcher(graph, ['a', 'b', 'c'], positions={'c': 'W2.1'})
    for name, at in (('a', 'W1.1'), ('b', 'W3.1'), ('c', '')):
        d.on_state(name, _placed(graph, name, at), 0.0)
    d.set_online('a', False)
    d.set_online('c', False)
    d.submit(TransportOrder('t1', 'W1', 'W2'))
    ((truck, name, order),) = d.step(0.0)  # a stands at W1.1, but only b is reachable
    assert (truck, name, order.order_id) == ('b', 'order', 't1')
    d.submit(TransportOrder('t2', 'W3', 'W0'))
    assert d.step(0.1) == [] and [t.id for t in d.queue] == ['t2']
    d.set_online('c', True)
    ((truck, name, init),) = d.step(0.2)
    assert (truck, name, init.actions[0].action_type) == ('c', 'instantActions', 'initPosition')
    d.set_online('a', True)
    d.step(0.3)  # its order waits for the block b stands in
    assert d.assignments == {'t1': 'b', 't2': 'a'}
