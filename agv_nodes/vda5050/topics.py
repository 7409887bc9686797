"""MQTT topic names, QoS levels and retain flags of the six VDA 5050 topics (6.2, 6.3, 6.5).

The bridge publishes and subscribes with exactly these; a master control expects them.
"""

from dataclasses import dataclass

from pydantic import BaseModel

from agv_nodes.vda5050 import INTERFACE, MAJOR
from agv_nodes.vda5050.connection import Connection
from agv_nodes.vda5050.factsheet import Factsheet
from agv_nodes.vda5050.order import InstantActions, Order
from agv_nodes.vda5050.state import State, Visualization

MASTER_CONTROL, AGV = 'master control', 'AGV'


@dataclass(frozen=True)
class Topic:
    """One topic: who publishes it, its message, and how MQTT is to carry it."""

    name: str
    publisher: str  # MASTER_CONTROL or AGV (6.5)
    message: type[BaseModel]
    qos: int  # MQTT QoS level
    retain: bool  # MQTT retain flag


TOPICS = {t.name: t for t in (
    # 6.2: QoS 0 for order, instantActions, state, factsheet and visualization; no section asks
    # for the retain flag on order, instantActions, state or visualization.
    Topic('order', MASTER_CONTROL, Order, qos=0, retain=False),  # 6.2, 6.6
    Topic('instantActions', MASTER_CONTROL, InstantActions, qos=0, retain=False),  # 6.2, 6.9
    Topic('state', AGV, State, qos=0, retain=False),  # 6.2, 6.10
    Topic('visualization', AGV, Visualization, qos=0, retain=False),  # 6.2, 6.13
    # 6.2 and 6.14: QoS 1; 6.14: every message retained, the last will too.
    Topic('connection', AGV, Connection, qos=1, retain=True),
    # 6.2: QoS 0; 6.15: every message retained.
    Topic('factsheet', AGV, Factsheet, qos=0, retain=True),
)}

# 6.3: '/' separates topic levels and '$' marks brokers' internal topics; '+' and '#' are MQTT
# wildcards, which no published topic may contain.
_FORBIDDEN = '/$+#'


def topic(manufacturer: str, serial_number: str, name: str, *,
          interface: str = INTERFACE) -> str:
    """Return the topic `uagv/v2/<manufacturer>/<serialNumber>/<name>` (6.3).

    Raises ValueError for a name that is not one of TOPICS, or a level that is empty or holds
    a character 6.3 or MQTT forbids there.
    """
    if name not in TOPICS:
        raise ValueError(f'{name!r} is not a VDA 5050 topic ({", ".join(TOPICS)})')
    for level in (interface, manufacturer, serial_number):
        if not level or any(c in level for c in _FORBIDDEN):
            raise ValueError(f'{level!r} cannot be a topic level: empty, or holds one of '
                             f'{_FORBIDDEN!r}')
    return f'{interface}/{MAJOR}/{manufacturer}/{serial_number}/{name}'
