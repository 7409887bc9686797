"""A fleet in lock step driven by a VDA 5050 master through each truck's bridge, without MQTT.

Each truck of an agv_nodes.fleet.lockstep.Fleet gets the bridge core the vda5050_bridge node
runs (agv_nodes.vda5050.bridge.BridgeCore). What a master sends a truck goes in as JSON text, as
it would arrive from the broker, and the states the bridge answers with go back to the master
parsed from their JSON text; the truck's side is its communications core: the bridge's tasks go
in as comms/task does, and the lines communications writes come back as comms/report does. So
the whole path but the two transports (DDS, MQTT) is the graph's, deterministic and seeded.

A master is anything with `on_state(truck, state, now)` and `step(now)`, which returns the
messages to send as (truck, topic name, message): the dispatcher
(agv_nodes.fleet.dispatcher), or a test's own.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any, Protocol

from pydantic import BaseModel

from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.harness import run_for
from agv_nodes.vda5050.bridge import BridgeCore, Outbox
from agv_nodes.vda5050.codec import parse, to_json
from agv_nodes.vda5050.state import State
from agv_nodes.vda5050.truck_factsheet import truck_factsheet
from agv_nodes.world.layout import layout_path, load_layout

MANUFACTURER = 'agv_nodes'


class Master(Protocol):
    """What drives the fleet: states in, VDA 5050 messages out."""

    def on_state(self, truck: str, state: State, now: float) -> None: ...

    def step(self, now: float) -> list[tuple[str, str, BaseModel]]: ...


class BridgedFleet:
    """See the module docstring."""

    def __init__(self, fleet: Fleet, master: Master, layout_name: str = 'demo_1983',
                 graph: TrackGraph | None = None, master_period: float = 0.1) -> None:
        self.fleet, self.master = fleet, master
        self.graph = graph or track_graph(load_layout(layout_path(layout_name)))
        self.bridges = {name: BridgeCore(self.graph, MANUFACTURER, name,
                                         factsheet=partial(truck_factsheet, MANUFACTURER, name))
                        for name in fleet.names}
        self.master_period = master_period  # s of sim time between the master's steps
        self._next_master = 0.0
        self.sent: list[tuple[float, str, str, BaseModel]] = []  # what the master sent
        self.states: dict[str, State] = {}  # each truck's last state
        self._connected = False

    @property
    def now(self) -> float:
        """Simulated seconds."""
        return self.fleet.now

    def _apply(self, truck: str, out: Outbox) -> None:
        for text in out.tasks:
            self.fleet.submit(truck, text)
        for topic, message in out.messages:
            if topic == 'state':  # as the master would read it off the wire
                state = parse(State, to_json(message))
                self.states[truck] = state
                self.master.on_state(truck, state, self.now)

    def step(self) -> None:
        """One world sample; then the trucks' reports to their bridges; then the master.

        Before the first sample every bridge connects: its first state tells the master where
        the truck stands.
        """
        if not self._connected:
            self._connected = True
            for name, bridge in self.bridges.items():
                self._apply(name, bridge.reconnected(None, self.now))
        self.fleet.step()
        now = self.now
        for name, bridge in self.bridges.items():
            for text in self.fleet.take_notes(name):
                self._apply(name, bridge.on_report(text, now))
            self._apply(name, bridge.tick(now))
        if now + 1e-12 >= self._next_master:
            self._next_master = now + self.master_period
            for truck, topic, message in self.master.step(now):
                self.sent.append((now, truck, topic, message))
                self._apply(truck, self.bridges[truck].on_message(topic, to_json(message), now))

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step for `seconds` of simulated time, or until `until()` is true (returns it)."""
        return run_for(self, seconds, until)

    def summary(self) -> dict[str, Any]:
        """Return each truck's last node, driving flag and errors, and the collisions."""
        return {'time': self.now, 'collisions': list(self.fleet.collisions),
                'trucks': {name: (s.last_node_id, s.driving, [e.error_type for e in s.errors])
                           for name, s in self.states.items()}}
