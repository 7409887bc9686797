"""One truck's VDA 5050 face in agv-fleet-sim: its bridge core and its own MQTT link.

What the vda5050_bridge node does for a launched truck (agv_nodes.vda5050.bridge_node), done
for a truck of a lock-step fleet: the ROS-free BridgeCore takes the master's `order` and
`instantActions` and the truck's communications lines, and its messages go out on the truck's
own MqttLink (client id `<manufacturer>_<serialNumber>`, last will CONNECTIONBROKEN on
`connection`, QoS 1 retained), with each topic's QoS and retain flag (agv_nodes.vda5050.topics).
`visualization` (6.13) carries the truck's pose as the world has it, at its own period.

paho delivers on its network thread; messages and connection changes wait in queues that
`poll` empties in the simulator's thread, at a simulated time. Until `poll` has taken the link's
coming up (and the bridge said ONLINE, the factsheet and the state) the face publishes nothing:
a master hears a truck's connection before its states. The broker link can be cut on
purpose (the `brokerLink` fault): the socket is dropped without DISCONNECT, so the broker
publishes the last will; mending it connects a new link and the bridge says ONLINE, the
factsheet and the state, with the gap in simulated seconds.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
import inspect
import math
from typing import Any

from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.mqtt.client import LastWill, MqttLink
from agv_nodes.vda5050.bridge import INBOUND, BridgeCore, Outbox
from agv_nodes.vda5050.codec import to_json
from agv_nodes.vda5050.connection import ConnectionState
from agv_nodes.vda5050.state import AgvPosition, Velocity, Visualization
from agv_nodes.vda5050.topics import TOPICS, topic
from agv_nodes.vda5050.truck_factsheet import truck_factsheet
from agv_nodes.vda5050.truck_records import RecordTap

CONNECT_TIMEOUT = 10.0  # wall s a truck's link may take to be accepted at the start


def _own_visualization(map_id: str) -> dict[str, Any]:
    """Return the bridge's arguments that leave visualization to the face (the world's pose).

    A bridge core that reckons agvPosition from the truck's records has its own visualization
    timer; the face sends the world's pose instead, as it does for a core without one.
    """
    known = inspect.signature(BridgeCore).parameters
    return {'visualization_interval': 0.0, 'map_id': map_id} \
        if 'visualization_interval' in known else {}


class TruckFace:
    """See the module docstring."""

    def __init__(self, serial_number: str, url: str, graph: TrackGraph, *, manufacturer: str,
                 interface: str, map_id: str, state_interval: float) -> None:
        self.name, self.url, self.map_id = serial_number, url, map_id
        self.bridge = BridgeCore(
            graph, manufacturer, serial_number,
            factsheet=lambda n: truck_factsheet(manufacturer, serial_number, n,
                                                state_interval=state_interval),
            state_interval=state_interval, **_own_visualization(map_id))
        self.records = RecordTap(self.bridge)  # the truck's records, each judged by a reader
        self.topics = {name: topic(manufacturer, serial_number, name, interface=interface)
                       for name in TOPICS}
        self.client_id = f'{manufacturer}_{serial_number}'
        self._inbox: deque[tuple[str, bytes]] = deque()
        self._changes: deque[bool] = deque()
        self.link: MqttLink | None = None
        self.up = False  # the link's coming up taken by `poll` (ONLINE said), until it drops
        self.cut_at: float | None = None  # sim s the broker link was cut, while it is
        self.sent = 0  # messages published

    # --- the broker link ---------------------------------------------------------------------

    def connect(self, wait: bool = True) -> None:
        """Open a new link with the last will; with `wait`, until the broker accepted it."""
        will = self.bridge.connection(ConnectionState.CONNECTIONBROKEN)
        link = MqttLink(self.url, self.client_id,
                        LastWill(self.topics['connection'], to_json(will), qos=1, retain=True),
                        reconnect_min_s=0.5, reconnect_max_s=5.0)
        link.on_connection(self._changes.append)
        for name in INBOUND:
            link.subscribe(self.topics[name], TOPICS[name].qos,
                           lambda _t, payload, name=name: self._inbox.append((name, payload)))
        link.connect(timeout=CONNECT_TIMEOUT if wait else None)
        self.link = link

    def cut(self, now: float) -> None:
        """Drop the link as a crash would: the broker publishes the last will."""
        if self.link is not None:
            self.link.close(clean=False)
            self.link, self.cut_at, self.up = None, now, False
            self._changes.clear()
            self._inbox.clear()  # what paho had taken was lost with the link

    def mend(self) -> None:
        """Connect again after a cut (the bridge says ONLINE when the link is up: poll)."""
        if self.link is None:
            self.connect(wait=False)

    def close(self) -> None:
        """Say OFFLINE (6.14) and disconnect cleanly: the broker drops the last will."""
        if self.link is not None:
            if self.link.connected:
                self.up = True  # OFFLINE goes out whether or not `poll` saw the link come up
                self.send(Outbox(messages=[('connection',
                                            self.bridge.connection(ConnectionState.OFFLINE))]))
            self.link.close(clean=True)
            self.link, self.up = None, False

    # --- the simulator's thread --------------------------------------------------------------

    def poll(self, now: float) -> Outbox:
        """Take the link's changes and the master's messages; keep the state interval."""
        out = Outbox()
        while self._changes:
            self.up = self._changes.popleft()
            if self.up:
                gap = None if self.cut_at is None else now - self.cut_at
                self.cut_at = None
                out.extend(self.bridge.reconnected(gap, now))
        while self._inbox:
            name, payload = self._inbox.popleft()
            out.extend(self.bridge.on_message(name, payload, now))
        out.extend(self.bridge.tick(now))
        return out

    def read(self, records: Iterable[tuple[str, bytes, float]], now: float) -> Outbox:
        """Give the bridge the truck's records (record, 16 bytes, sent at on the truck's clock).

        Each is judged by its reader as the bridge node's readers judge them (a rejected one
        is counted in `self.records.readers` and dropped); what the bridge answers is returned.
        """
        for record, raw, sent_at in records:
            self.records.read(record, raw, sent_at, now)
        return self.records.take()

    def send(self, out: Outbox) -> None:
        """Publish the bridge's messages (its tasks are the caller's: to the truck)."""
        if self.link is None or not self.up:
            # cut, or not up yet: what the truck would say is lost, as on a truck whose radio
            # is down; once up, ONLINE, the factsheet and the state go first (`poll`)
            return
        for name, message in out.messages:
            spec = TOPICS[name]
            self.link.publish(self.topics[name], to_json(message), spec.qos, spec.retain)
            self.sent += 1

    def visualization(self, pose: tuple[float, float, float, float]) -> Outbox:
        """Return the truck's visualization: its pose and speed as the world has them.

        `pose` is the reference point's (x, y, heading, speed): the front axle centre, the
        point agvPosition names (fleet_sim_faults.reference_pose).
        """
        x, y, heading, speed = pose
        theta = math.atan2(math.sin(heading), math.cos(heading))  # in [-pi, pi] (6.10.6)
        message = Visualization(
            **self.bridge.header('visualization'),
            agv_position=AgvPosition(position_initialized=True, x=x, y=y, theta=theta,
                                     map_id=self.map_id),
            velocity=Velocity(vx=speed, vy=0.0, omega=None))
        return Outbox(messages=[('visualization', message)])
