"""A VDA 5050 master control for the tests, written apart from the bridge it drives.

It speaks plain paho-mqtt and hand-written JSON with the standard's field names (section 6), so
a misreading of the standard in the bridge's models does not cancel out here. Every message it
receives from the truck is checked against the standard's own JSON schema
(test/data/vda5050_2.1.0) before a test sees it.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, datetime
import json
from pathlib import Path
import re
import threading
import time
from typing import Any

from jsonschema.validators import validator_for
from paho.mqtt.client import Client, MQTTv311
from paho.mqtt.enums import CallbackAPIVersion

SCHEMAS = Path(__file__).parent / 'data' / 'vda5050_2.1.0'
FROM_TRUCK = ('state', 'connection', 'factsheet', 'visualization')
# Where the 2.1.0 schema contradicts the standard's text, the text applies (as in
# test_vda5050_messages.py): the factsheet schema puts the blockingTypes enum on the array
# itself, which no array of blocking types (6.15.1) can satisfy.
SCHEMA_FLAWS = (re.compile(r"^protocolFeatures/agvActions/\d+/blockingTypes: \[.*\] is not one "
                           r"of \['NONE', 'SOFT', 'HARD'\]$"),)


def _validator(name: str) -> Any:
    schema = json.loads((SCHEMAS / f'{name}.schema').read_text(encoding='utf-8'))
    return validator_for(schema)(schema)


def stamp() -> str:
    """Return an ISO 8601 UTC timestamp with milliseconds, as 6.4 asks."""
    return datetime.now(UTC).isoformat(timespec='milliseconds').replace('+00:00', 'Z')


def node(node_id: str, sequence_id: int, released: bool = True,
         actions: list[dict] | None = None) -> dict:
    """Return an order node (6.6.6)."""
    return {'nodeId': node_id, 'sequenceId': sequence_id, 'released': released,
            'actions': actions or []}


def edge(start: str, end: str, sequence_id: int, released: bool = True) -> dict:
    """Return an order edge (6.6.6) named as the track graph names its edges."""
    return {'edgeId': f'{start}-{end}', 'sequenceId': sequence_id, 'released': released,
            'startNodeId': start, 'endNodeId': end, 'actions': []}


def action(action_type: str, action_id: str, **parameters: Any) -> dict:
    """Return an action (6.8) with HARD blocking."""
    return {'actionType': action_type, 'actionId': action_id, 'blockingType': 'HARD',
            'actionParameters': [{'key': k, 'value': v} for k, v in parameters.items()]}


def path(node_ids: list[str], first_sequence: int = 0, released: int | None = None,
         actions: dict[str, list[dict]] | None = None) -> tuple[list[dict], list[dict]]:
    """Return (nodes, edges) along `node_ids`; the first `released` nodes are the base."""
    actions = actions or {}
    released = len(node_ids) if released is None else released
    nodes, edges = [], []
    for i, n in enumerate(node_ids):
        seq = first_sequence + 2 * i
        nodes.append(node(n, seq, i < released, actions.get(n)))
        if i:
            edges.append(edge(node_ids[i - 1], n, seq - 1, i < released))
    return nodes, edges


class Master:
    """One master control for one truck: publish orders and instant actions, collect replies."""

    def __init__(self, url: str, manufacturer: str, serial_number: str) -> None:
        host, port = url.removeprefix('mqtt://').rsplit(':', 1)
        self.prefix = f'uagv/v2/{manufacturer}/{serial_number}'
        self.manufacturer, self.serial_number = manufacturer, serial_number
        self.received: dict[str, list[dict]] = {name: [] for name in FROM_TRUCK}
        self.invalid: list[tuple[str, str]] = []  # (topic, schema error) of what the truck sent
        self._validators = {name: _validator(name) for name in FROM_TRUCK}
        self._lock = threading.Lock()
        self._header = 0
        self._subscribed = threading.Event()
        self.client = Client(callback_api_version=CallbackAPIVersion.VERSION2,
                             client_id=f'test_master_{serial_number}', protocol=MQTTv311)
        self.client.on_message = self._on_message
        self.client.on_subscribe = lambda *_args: self._subscribed.set()
        # subscribed again on every connect: a clean session forgets it (a restarted broker)
        self.client.on_connect = lambda client, *_args: client.subscribe(f'{self.prefix}/+', 1)
        self.client.reconnect_delay_set(0.2, 1.0)
        self.client.connect(host, int(port))
        self.client.loop_start()
        assert self._subscribed.wait(10), 'the broker did not grant the master its subscription'

    def _on_message(self, _client: Any, _userdata: Any, message: Any) -> None:
        name = message.topic.rsplit('/', 1)[1]
        if name not in FROM_TRUCK:
            return  # our own order / instantActions echoed back
        doc = json.loads(message.payload)
        errors = [f'{"/".join(map(str, e.path))}: {e.message}'
                  for e in self._validators[name].iter_errors(doc)]
        errors = [e for e in errors if not any(flaw.match(e) for flaw in SCHEMA_FLAWS)]
        with self._lock:
            self.received[name].append(doc)
            self.invalid += [(name, e) for e in errors]

    def _send(self, name: str, body: dict) -> dict:
        doc = {'headerId': self._header, 'timestamp': stamp(), 'version': '2.1.0',
               'manufacturer': self.manufacturer, 'serialNumber': self.serial_number, **body}
        self._header += 1
        self.client.publish(f'{self.prefix}/{name}', json.dumps(doc), qos=0).wait_for_publish(5)
        return doc

    def order(self, order_id: str, update_id: int, nodes: list[dict], edges: list[dict]) -> dict:
        """Publish an order (6.6)."""
        return self._send('order', {'orderId': order_id, 'orderUpdateId': update_id,
                                    'nodes': nodes, 'edges': edges})

    def instant(self, *actions: dict) -> dict:
        """Publish instant actions (6.9)."""
        return self._send('instantActions', {'actions': list(actions)})

    def raw(self, name: str, payload: str) -> None:
        """Publish a payload as it is (bad input)."""
        self.client.publish(f'{self.prefix}/{name}', payload, qos=0).wait_for_publish(5)

    def states(self) -> list[dict]:
        """Return every state received so far."""
        with self._lock:
            return list(self.received['state'])

    def wait_for(self, name: str, condition: Callable[[dict], bool], wall_limit: float,
                 what: str, spin: Callable[[], None] | None = None) -> dict:
        """Return the first message on `name` (from now on or before) meeting `condition`."""
        deadline = time.monotonic() + wall_limit
        while time.monotonic() < deadline:
            with self._lock:
                hit = next((m for m in self.received[name] if condition(m)), None)
            if hit is not None:
                return hit
            if spin is not None:
                spin()
            else:
                time.sleep(0.05)
        with self._lock:
            last = self.received[name][-1:] or None
        raise AssertionError(f'no {name} with {what} within {wall_limit:g} s; last: {last}')

    def close(self) -> None:
        """Disconnect."""
        self.client.disconnect()
        self.client.loop_stop()
