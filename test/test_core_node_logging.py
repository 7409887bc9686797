"""A core's notes reach the node's log at either severity, in any order."""

import pytest
from rclpy.logging import get_logger

from agv_nodes.core_node import CoreNode

pytestmark = pytest.mark.timeout(30)


class _Logged:
    """Stands in for the node: say() needs only its logger (one object, as a node's is)."""

    def __init__(self) -> None:
        self.logger = get_logger('core_node_logging_test')

    def get_logger(self):  # noqa: ANN201 - an rclpy logger
        return self.logger


def test_warn_and_info_notes_alternate_without_error() -> None:
    # rclpy keys a log call's settings on its call site and raises ValueError when one site
    # logs at two severities: a route following that warned (no_track) and then informed (a
    # new leg) died of it.
    node = _Logged()
    for level in ('warn', 'info', 'warn', 'info'):
        CoreNode.say(node, f'a {level} note', level)
