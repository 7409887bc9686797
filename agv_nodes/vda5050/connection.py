"""The connection message (6.14): whether a truck is connected to the MQTT broker.

The truck sends 'ONLINE' when it connects and 'OFFLINE' before it disconnects on purpose; it
registers 'CONNECTIONBROKEN' as its MQTT last will, which the broker sends when the connection
ends unexpectedly (so that message's header is as old as the connection).
"""

from enum import StrEnum

from agv_nodes.vda5050.common import Header


class ConnectionState(StrEnum):
    """State of the connection between truck and broker (6.14)."""

    ONLINE = 'ONLINE'
    OFFLINE = 'OFFLINE'  # ended in a coordinated way
    CONNECTIONBROKEN = 'CONNECTIONBROKEN'  # ended unexpectedly: the last will


class Connection(Header):
    """The connection message (6.14)."""

    connection_state: ConnectionState
