"""What a node on the VDA 5050 link takes from its parameters: its broker and its track graph.

The truck's bridge and the fleet's dispatcher both name a broker (`mqtt_url`, else the
AGV_MQTT_URL environment variable) and a layout whose track graph their orders are drawn on; a
bad value stops either at start-up with one line naming the parameter and value.
"""

from __future__ import annotations

import os

from rclpy.node import Node

from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.mqtt.client import ENV_URL, parse_mqtt_url
from agv_nodes.params import parameter_error
from agv_nodes.world.layout import LayoutError, layout_path, load_layout


def broker_parameter(node: Node, mqtt_url: str) -> str:
    """Return the broker's URL: `mqtt_url`, else AGV_MQTT_URL; checked."""
    url = mqtt_url or os.environ.get(ENV_URL, '')
    if not url:
        raise parameter_error(node, 'mqtt_url', mqtt_url, f'empty and {ENV_URL} unset: '
                              'no broker to connect to')
    try:
        parse_mqtt_url(url)
    except ValueError as exc:
        raise parameter_error(node, 'mqtt_url', url, str(exc)) from None
    return url


def graph_parameter(node: Node, layout: str) -> TrackGraph:
    """Return the track graph of the layout named by parameter `layout`."""
    try:
        return track_graph(load_layout(layout_path(layout)))
    except (LayoutError, OSError) as exc:
        raise parameter_error(node, 'layout', layout, str(exc)) from None
