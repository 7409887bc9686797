"""What a node on the VDA 5050 link takes from its parameters: its broker and its track graph.

The truck's bridge and the fleet's dispatcher both name a broker (`mqtt_url`, else the
AGV_MQTT_URL environment variable) and a layout whose track graph their orders are drawn on; a
bad value stops either at start-up with one line naming the parameter and value. A secured
broker adds TLS files (`tls_ca`, `tls_cert`, `tls_key`, for an mqtts:// URL) and a user name
(`username`) whose password comes from `password_file`, else the AGV_MQTT_PASSWORD environment
variable: never from a parameter value, which `ros2 param get` and the launch's files show.
"""

from __future__ import annotations

import os
import ssl
from typing import Any

from rclpy.node import Node

from agv_nodes.fleet.track_graph import TrackGraph, track_graph
from agv_nodes.mqtt.address import (
    ENV_PASSWORD,
    ENV_URL,
    LinkSecurity,
    parse_mqtt_url,
    read_password,
    uses_tls,
)
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


def security_parameters(node: Node, settings: Any, url: str) -> LinkSecurity:
    """Return the link's TLS files and credentials from `settings` (checked against `url`).

    `settings` has tls_ca, tls_cert, tls_key, username and password_file (strings, '' unset).
    """
    files = {name: getattr(settings, name) for name in ('tls_ca', 'tls_cert', 'tls_key')}
    for name, path in files.items():
        if path and not uses_tls(url):
            raise parameter_error(node, name, path, f'TLS files apply to mqtts:// only, and the '
                                  f'broker is {url}: give an mqtts:// URL or no TLS files')
        if path and not os.access(path, os.R_OK):
            raise parameter_error(node, name, path, 'no such file, or not readable')
    if bool(files['tls_cert']) != bool(files['tls_key']):
        name = 'tls_key' if files['tls_cert'] else 'tls_cert'
        raise parameter_error(node, name, files[name], 'a client certificate needs its key '
                              '(tls_cert and tls_key): give both or neither')
    _check_pem(node, files)
    username, password_file = settings.username, settings.password_file
    try:
        password = read_password(password_file)
    except ValueError as exc:
        raise parameter_error(node, 'password_file', password_file, str(exc)) from None
    if password and not username:
        source = 'password_file' if password_file else ENV_PASSWORD
        raise parameter_error(node, 'username', username, f'a password is given ({source}) '
                              'but no user name')
    return LinkSecurity(ca_file=files['tls_ca'], cert_file=files['tls_cert'],
                        key_file=files['tls_key'], username=username, password=password)


def _check_pem(node: Node, files: dict[str, str]) -> None:
    """Load the TLS files as paho will, so a file that is not PEM stops here in one line."""
    context = ssl.create_default_context()
    try:
        if files['tls_ca']:
            context.load_verify_locations(cafile=files['tls_ca'])
    except (ssl.SSLError, OSError) as exc:
        raise parameter_error(node, 'tls_ca', files['tls_ca'], f'not a PEM CA certificate '
                              f'({exc})') from None
    try:
        if files['tls_cert']:
            context.load_cert_chain(files['tls_cert'], files['tls_key'])
    except (ssl.SSLError, OSError) as exc:
        raise parameter_error(node, 'tls_cert', files['tls_cert'], 'not a PEM certificate '
                              f'whose key is tls_key ({exc})') from None


def graph_parameter(node: Node, layout: str) -> TrackGraph:
    """Return the track graph of the layout named by parameter `layout`."""
    try:
        return track_graph(load_layout(layout_path(layout)))
    except (LayoutError, OSError) as exc:
        raise parameter_error(node, 'layout', layout, str(exc)) from None
