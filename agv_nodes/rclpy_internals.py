"""Every use of rclpy's private attributes, in one place, checked against the version they are for.

rclpy offers no public way to (1) drop the ROS clock's own /clock reader when a node reads
/clock itself (`TimeSource._clock_sub`), (2) see what a node was asked to set before it declares
a parameter (`Node._parameter_overrides`), or (3) take every queued message of a subscription
without an executor turn each (`Subscription.handle.take_message`). Each is used for a measured
reason (the callers say which). They were written against rclpy 7.1 (ROS 2 Jazzy); on another
version each function checks that what it needs is there and falls back to doing without it,
and `check_version` says once that the fallbacks may be in use. test/test_rclpy_internals.py
exercises all three against the installed rclpy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
import functools
from importlib import metadata
import sys
from typing import Any

TESTED = ('7.1',)  # rclpy major.minor these are written for


@functools.cache
def rclpy_version() -> str:
    """Return the installed rclpy's version ('' when it cannot be told)."""
    for dist in ('ros-jazzy-rclpy', 'rclpy'):
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    try:  # a ROS install: the package manifest
        import xml.etree.ElementTree as ElementTree

        from ament_index_python.packages import get_package_share_directory

        root = ElementTree.parse(f'{get_package_share_directory("rclpy")}/package.xml')
        return root.findtext('version') or ''
    except Exception:  # noqa: BLE001 - no ament index, or no rclpy in it
        return ''


@functools.cache
def check_version() -> bool:
    """Return True when the installed rclpy is one these were written for; else say so once."""
    version = rclpy_version()
    ok = '.'.join(version.split('.')[:2]) in TESTED
    if not ok:
        print(f'agv_nodes: rclpy {version or "(unknown version)"} is not one of '
              f'{", ".join(TESTED)}: private attributes are used only where present',
              file=sys.stderr)
    return ok


def drop_clock_reader(node: Any) -> Any | None:
    """Destroy the /clock subscription of `node`'s TimeSource and return the TimeSource.

    The caller can then feed it. None when this rclpy does not have one where expected.
    """
    check_version()
    time_source = getattr(node, '_time_source', None)
    own = getattr(time_source, '_clock_sub', None)
    if own is None:
        return None
    node.destroy_subscription(own)
    time_source._clock_sub = None
    return time_source


def parameter_overrides(node: Any) -> Mapping[str, Any]:
    """Return the values `node` was given for its parameters (files and -p), by name.

    Empty when this rclpy keeps them elsewhere.
    """
    check_version()
    overrides = getattr(node, '_parameter_overrides', None)
    return {name: getattr(p, 'value', p) for name, p in (overrides or {}).items()}


def take_all(subscription: Any, limit: int) -> Iterator[tuple[bytes, dict[str, Any]]]:
    """Take (serialized message, message info) of each message queued on a raw subscription.

    Oldest first, at most `limit`.
    """
    check_version()
    handle = subscription.handle
    for _ in range(limit):
        with handle:
            taken = handle.take_message(subscription.msg_type, True)
        if taken is None:
            return
        yield taken
