"""Every use of rclpy's private attributes, in one place, checked against the version they are for.

rclpy offers no public way to (1) drop the ROS clock's own /clock reader when a node reads
/clock itself (`TimeSource._clock_sub`), (2) see what a node was asked to set before it declares
a parameter (`Node._parameter_overrides`), (3) take every queued message of a subscription
without an executor turn each (`Subscription.handle.take_message`), or (4) learn which writer
sent a message (its message info has no publisher GID): `WriterTaggedSubscription` takes a
record topic's messages itself through librcl with ctypes, in a Waitable both executors run.
Each is used for a measured reason (the callers say which). They were written against rclpy 7.1
(ROS 2 Jazzy); on another version each function checks that what it needs is there and falls
back to doing without it, and `check_version` says once that the fallbacks may be in use.
test/test_foundation.py exercises the first three and test/test_rclpy_internals.py the fourth
against the installed rclpy.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
import ctypes
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
    if own is None or time_source is None:
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


# -- per-sample writer identity: take a subscription's messages through librcl --------------------
# rclpy 7.1 gives no publisher GID in its message info, but rcl's does (rmw_message_info_t). So a
# record reader takes its messages itself, serialized, with ctypes through librcl. Its
# subscription is kept out of the node's subscription list (no executor takes its messages
# first) and goes into a Waitable instead: both the SingleThreadedExecutor (wait sets) and the
# EventsExecutor (which sets its own on-new-message callback on a Waitable's subscriptions, so no
# Python runs on a DDS thread) hand it to us on the executor thread, one message per event, in
# arrival order with the node's other inputs.

RCL_RET_OK = 0
RCL_RET_SUBSCRIPTION_TAKE_FAILED = 401
GID_SIZE = 16  # RMW_GID_STORAGE_SIZE in Jazzy's rmw


class _Gid(ctypes.Structure):
    _fields_ = [('implementation_identifier', ctypes.c_char_p),
                ('data', ctypes.c_uint8 * GID_SIZE)]


class _MessageInfo(ctypes.Structure):  # rmw_message_info_t (rmw/types.h, Jazzy)
    _fields_ = [('source_timestamp', ctypes.c_int64), ('received_timestamp', ctypes.c_int64),
                ('publication_sequence_number', ctypes.c_uint64),
                ('reception_sequence_number', ctypes.c_uint64), ('publisher_gid', _Gid),
                ('from_intra_process', ctypes.c_bool)]


class _Allocator(ctypes.Structure):  # rcutils_allocator_t
    _fields_ = [('allocate', ctypes.c_void_p), ('deallocate', ctypes.c_void_p),
                ('reallocate', ctypes.c_void_p), ('zero_allocate', ctypes.c_void_p),
                ('state', ctypes.c_void_p)]


class _Uint8Array(ctypes.Structure):  # rcutils_uint8_array_t = rcl_serialized_message_t
    _fields_ = [('buffer', ctypes.POINTER(ctypes.c_uint8)), ('buffer_length', ctypes.c_size_t),
                ('buffer_capacity', ctypes.c_size_t), ('allocator', _Allocator)]


@functools.cache
def _libraries() -> tuple[ctypes.CDLL, ctypes.CDLL] | str:
    """(librcl, librcutils) with the functions typed, or why they cannot be used."""
    try:
        rcl = ctypes.CDLL('librcl.so')  # the copy rclpy loaded (same soname)
        rcutils = ctypes.CDLL('librcutils.so')
        take = rcl.rcl_take_serialized_message
        default_allocator = rcutils.rcutils_get_default_allocator
        array_init = rcutils.rcutils_uint8_array_init
        array_fini = rcutils.rcutils_uint8_array_fini
        reset_error = rcutils.rcutils_reset_error
    except (OSError, AttributeError) as exc:
        return f'librcl or librcutils not usable ({exc})'
    take.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Uint8Array),
                     ctypes.POINTER(_MessageInfo), ctypes.c_void_p]
    take.restype = ctypes.c_int32
    default_allocator.argtypes = []
    default_allocator.restype = _Allocator
    array_init.argtypes = [ctypes.POINTER(_Uint8Array), ctypes.c_size_t,
                           ctypes.POINTER(_Allocator)]
    array_init.restype = ctypes.c_int32
    array_fini.argtypes = [ctypes.POINTER(_Uint8Array)]
    array_fini.restype = ctypes.c_int32
    reset_error.argtypes = []
    reset_error.restype = None
    return rcl, rcutils


@functools.cache
def writer_identity_unavailable() -> str:
    """Return why per-sample writer identity cannot be had here ('' when it can); said once."""
    check_version()
    libraries = _libraries()
    why = libraries if isinstance(libraries, str) else ''
    if not why:
        try:
            from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
            from rclpy.waitable import NumberOfEntities, Waitable  # noqa: F401
            _rclpy.Subscription  # noqa: B018 - only that it is there
        except (ImportError, AttributeError) as exc:
            why = f'rclpy has no raw subscription or Waitable ({exc})'
    if why:
        _say_once(f'record writer identity check off: {why}')
    return why


@functools.cache
def _say_once(text: str) -> None:
    print(f'agv_nodes: {text}', file=sys.stderr)


class WriterTaggedSubscription:
    """A subscription whose messages come with their writer's GID: `on_sample(raw, gid, stamp)`.

    `raw` is the serialized message, `gid` the writer endpoint's 16-byte GID as the graph shows
    it (TopicEndpointInfo.endpoint_gid), `stamp` the writer's source timestamp (ns). Build it
    with `writer_tagged_subscription`, which returns None where this cannot work.
    """

    def __init__(self, node: Any, msg_type: type, topic: str, qos_profile: Any,
                 on_sample: Any) -> None:
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
        from rclpy.type_support import check_is_valid_msg_type
        from rclpy.waitable import NumberOfEntities, Waitable

        check_is_valid_msg_type(msg_type)  # also loads its type support, as rclpy does
        libraries = _libraries()
        if isinstance(libraries, str):  # writer_tagged_subscription asks first
            raise RuntimeError(f'writer tagged subscription: {libraries}')
        rcl, rcutils = libraries
        self._take_fn = rcl.rcl_take_serialized_message
        self._rcutils = rcutils
        self._node = node
        with node.handle:
            self.handle = _rclpy.Subscription(node.handle, msg_type, topic,
                                              qos_profile.get_c_qos_profile())
        self._pointer = self.handle.pointer
        self._msg = _Uint8Array()
        self._info = _MessageInfo()
        allocator = rcutils.rcutils_get_default_allocator()
        if rcutils.rcutils_uint8_array_init(ctypes.byref(self._msg), 64,
                                            ctypes.byref(allocator)) != RCL_RET_OK:
            raise MemoryError('rcutils_uint8_array_init failed')
        self._msg_ref, self._info_ref = ctypes.byref(self._msg), ctypes.byref(self._info)
        self._on_sample = on_sample
        # The first take checks the struct layout (the rmw's name is where the GID's is);
        # where it is not, messages come without a GID (None): the check is off.
        self.layout_ok: bool | None = None
        outer = self

        class _Ready(Waitable):
            def __init__(self) -> None:
                super().__init__(node.default_callback_group)
                self.index: int | None = None

            def __enter__(self) -> None:
                outer.handle.__enter__()

            def __exit__(self, *exc: Any) -> None:
                outer.handle.__exit__(*exc)

            def is_ready(self, wait_set: Any) -> bool:
                return self.index is not None and wait_set.is_ready('subscription', self.index)

            def take_data(self) -> None:
                # Handled here, not in execute: rclpy 7.1.6's EventsExecutor runs execute as a
                # Task posted behind every event already queued, so a node draining its queue
                # (the world between steps) would stop at each message and fall behind (a
                # parameter service took 19 s to answer instead of 0.4 s). Here the message is
                # handled in its own event, in arrival order.
                taken = outer.take()
                if taken is not None:
                    outer._on_sample(*taken)

            async def execute(self, _taken: None) -> None:
                return None

            def get_num_entities(self) -> Any:
                return NumberOfEntities(num_subs=1)

            def add_to_wait_set(self, wait_set: Any) -> None:
                self.index = wait_set.add_subscription(outer.handle)

        self.waitable = _Ready()
        node.add_waitable(self.waitable)
        self._destroyed = False
        # destroy_node frees the node's own subscriptions, not this one: left to the garbage
        # collector, its delete_datareader could hang Fast DDS at some later, unrelated
        # collection. So it goes, at the latest, when its context shuts down.
        node.context.on_shutdown(self.destroy)

    def take(self) -> tuple[bytes, bytes | None, int] | None:
        """Take one queued message: (serialized bytes, writer GID, source stamp) or None."""
        with self.handle:
            ret = self._take_fn(self._pointer, self._msg_ref, self._info_ref, None)
        if ret != RCL_RET_OK:
            self._rcutils.rcutils_reset_error()
            if ret != RCL_RET_SUBSCRIPTION_TAKE_FAILED:
                raise RuntimeError(f'rcl_take_serialized_message failed ({ret})')
            return None
        info = self._info
        if self.layout_ok is None:
            self.layout_ok = self._check_layout()
        return (ctypes.string_at(self._msg.buffer, self._msg.buffer_length),
                bytes(info.publisher_gid.data) if self.layout_ok else None,
                info.source_timestamp if self.layout_ok else 0)

    def _check_layout(self) -> bool:
        """Return True when the first message info names this rmw where the GID's name is."""
        from rclpy.utilities import get_rmw_implementation_identifier

        name = self._info.publisher_gid.implementation_identifier
        if name is not None and name.decode(errors='replace') == \
                get_rmw_implementation_identifier():
            return True
        _say_once(f'record writer identity check off: rmw_message_info_t is not laid out as '
                  f'in Jazzy (the GID names {name!r})')
        return False

    @property
    def sequence(self) -> int:
        """The writer's publication sequence number of the message last taken (0: unknown)."""
        return self._info.publication_sequence_number if self.layout_ok else 0

    def publisher_count(self) -> int:
        """Writers matched."""
        with self.handle:
            return self.handle.get_publisher_count()

    def destroy(self) -> None:
        """Leave the executor and free the subscription and its buffer (once)."""
        if self._destroyed:
            return
        self._destroyed = True
        if self.waitable in self._node.waitables:
            self._node.remove_waitable(self.waitable)
        self.handle.destroy_when_not_in_use()
        self._rcutils.rcutils_uint8_array_fini(self._msg_ref)


def writer_tagged_subscription(node: Any, msg_type: type, topic: str, qos_profile: Any,
                               on_sample: Any) -> WriterTaggedSubscription | None:
    """Return a WriterTaggedSubscription, or None where librcl cannot be used (said once)."""
    if writer_identity_unavailable():
        return None
    return WriterTaggedSubscription(node, msg_type, topic, qos_profile, on_sample)
