"""rclpy bindings of the record ports: a record topic carries std_msgs/UInt8MultiArray (16 bytes).

Nodes use these; the lock-step harness uses the ROS-free RecordWriter/RecordReader underneath
directly, so both share the codec, the schemas' port declarations and the E2E rules.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock as RosClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String, UInt8MultiArray

from agv_nodes import qos
from agv_nodes.rclpy_internals import writer_identity_unavailable, writer_tagged_subscription
from agv_nodes.records.carrier import clock_ns, uint8_array_cdr, uint8_array_data
from agv_nodes.records.ports import (
    DUPLICATE_WRITER,
    FOREIGN_WRITER,
    CountedInput,
    RecordReader,
    RecordWriter,
    WriterCheck,
    gid_writer,
    inputs_report,
    node_name,
)
from agv_nodes.records.schema import RecordSchema


class RecordPublisher(RecordWriter):
    """Publishes one record topic; `publish(fields)` packs and sends 16 bytes.

    The UInt8MultiArray goes out already serialized (agv_nodes.records.carrier): the same bytes
    rclpy would write, without building a Python message for each record.
    """

    def __init__(self, node: Node, schema: RecordSchema, integrity: str = 'e2e') -> None:
        super().__init__(schema, integrity if schema.protected else 'none')
        self._pub = node.create_publisher(UInt8MultiArray, schema.topic, qos.writer_qos(schema))

    def publish(self, fields: Mapping[str, Any]) -> bytes:
        """Pack `fields` and publish them; returns the 16 bytes sent."""
        raw = self.pack(fields)
        self._pub.publish(uint8_array_cdr(raw))
        return raw

    def publish_raw(self, raw: bytes) -> None:
        """Send bytes as they are (fault injection and foreign-writer tests only)."""
        self._pub.publish(uint8_array_cdr(bytes(raw)))

    @property
    def subscription_count(self) -> int:
        """Matched readers."""
        return self._pub.get_subscription_count()


def node_time(node: Node) -> Callable[[], int]:
    """Return the node's time in ns.

    A CoreNode's ros_now_s (its FIFO /clock under the EventsExecutor, see
    core_node.ClockTimers), else the ROS clock.
    """
    ros_now_s = getattr(node, 'ros_now_s', None)
    if ros_now_s is not None:
        return lambda: round(ros_now_s() * 1e9)
    return lambda: node.get_clock().now().nanoseconds


def record_bytes(raw: bytes) -> bytes:
    """Return the record in a serialized UInt8MultiArray.

    It is read straight from the CDR when it has the shape this package sends, else through
    rclpy's deserializer (a foreign writer's layout).
    """
    data = uint8_array_data(raw)
    if data is None:
        data = bytes(deserialize_message(raw, UInt8MultiArray).data)
    return data


def clock_time_ns(raw: bytes) -> int:
    """Return the time in a serialized rosgraph_msgs/Clock, ns.

    It is read straight from the CDR when it has the shape the world sends, else through
    rclpy's deserializer.
    """
    ns = clock_ns(raw)
    if ns is None:
        msg = deserialize_message(raw, Clock)
        ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
    return ns


def full_name(node: Node, name: str) -> str:
    """Return the full name of node `name` as seen from `node` (relative: its namespace).

    With one leading '/', as WriterCheck compares names. A `gid:<hex>` writer is no node
    name and is returned as it is.
    """
    if gid_writer(name) is not None:
        return name
    if name.startswith('/'):
        return node_name(name)
    return node_name(f'{node.get_namespace().rstrip("/")}/{name}')


def writer_name(node: Node, schema: RecordSchema | str, default: str | None = None) -> str:
    """Return the full name of the writer whose samples `node` takes on an input.

    The input is a record (its schema: the schema's writer by default) or a stop switch's
    name (`default` its writer), unless the node's `record_writers` setting names another (a
    hardware driver in its place: a node, or `gid:<hex>`).
    """
    writer_nodes = getattr(getattr(node, 'node_settings', None), 'writer_nodes', None)
    named = writer_nodes() if writer_nodes is not None else {}
    if isinstance(schema, str):
        return full_name(node, named.get(schema, default or ''))
    return full_name(node, named.get(schema.name, schema.writer))


def graph_writers(node: Node, topic: str) -> list[tuple[str, bytes]]:
    """Return `topic`'s writers as the graph shows them: (node's full name, endpoint GID)."""
    return [(node_name(f'{i.node_namespace.rstrip("/")}/{i.node_name}'), bytes(i.endpoint_gid))
            for i in node.get_publishers_info_by_topic(topic)]


# Wall seconds an input may wait for its named writer before it says so: past a start-up of
# the whole graph on a loaded machine (the world, started last, was seen 6 s after its readers
# on the shared 2-core machine), short enough to be read before anyone gives up.
WRITER_PATIENCE_S = 10.0


class WriterWatch:
    """Says once, on the log and in /diagnostics (`waiting`), that an input's writer is absent.

    Polls the graph once a wall second (a steady timer: sim time stands still until the world
    moves, which it does not while a writer is missing) until the input has taken a sample
    or its named writer is in the graph; says so past WRITER_PATIENCE_S, and clears it when
    the writer comes.
    """

    def __init__(self, node: Node, port: Any, name: str, topic: str) -> None:
        self._node, self._port, self._name, self._topic = node, port, name, topic
        self._since: float | None = None
        self._said = False
        self._steady = RosClock(clock_type=ClockType.STEADY_TIME)
        self._timer = node.create_timer(1.0, self.poll, clock=self._steady)

    def poll(self) -> None:
        """Check once; stop polling once the writer has been heard."""
        port, check = self._port, self._port.check
        now = self._steady.now().nanoseconds * 1e-9
        self._since = now if self._since is None else self._since
        there = any(check.names(node, gid) for node, gid in graph_writers(self._node,
                                                                           self._topic))
        if port.accepted or there:
            if self._said:
                self._node.get_logger().info(f'{self._name}: its writer {check.writer} is here')
            port.waiting, self._said = '', False
            if port.accepted:
                self._node.destroy_timer(self._timer)
            return
        if now - self._since >= WRITER_PATIENCE_S and not self._said:
            others = len(graph_writers(self._node, self._topic))
            port.waiting = (f'{self._name}: waiting for its writer {check.writer} on '
                            f'{self._topic} ({now - self._since:.0f} s; {others} other '
                            f'writer{"s" if others != 1 else ""} there)')
            self._node.get_logger().warning(port.waiting)
            self._said = True


class RecordSubscription(RecordReader):
    """Subscribes one record topic; calls `callback(fields)` for each record accepted.

    Only the topic's one genuine writer is heard (records.ports.WriterCheck): each message is
    taken with its writer's GID (rclpy_internals.WriterTaggedSubscription) and one from any
    other endpoint is rejected as `foreign_writer`, counted and never passed to `on_reject`, so
    a second writer can neither steer a node nor exhaust the rejection budget its core keeps
    for the genuine writer's faults. The genuine writer is the graph's node `writer` (full
    name; default `writer_name`). Where librcl cannot be used the check is off (said on stderr
    and in /diagnostics) and rclpy takes the messages. Either way they are taken serialized and
    the 16 bytes read from the CDR (`record_bytes`): a 340 Hz reader costs a node a third less
    CPU that way (agv_nodes.records.carrier).
    """

    def __init__(self, node: Node, schema: RecordSchema, integrity: str = 'e2e',
                 callback: Callable[[dict[str, Any]], None] | None = None,
                 sent_stamps: bool = False, writer: str | None = None) -> None:
        super().__init__(schema, integrity if schema.protected else 'none')
        self._node = node
        self._callback = callback
        self._now_ns = node_time(node)
        self.on_reject: Callable[[], None] | None = None  # told after each rejection but ours
        self.sent_ns = 0  # DDS source timestamp of the record being handled (writer's wall ns)
        self.writer = writer or writer_name(node, schema)
        self.check = WriterCheck(self.writer, self._graph_writers)
        self.writer = self.check.writer
        self._current: bytes | None = None  # the genuine writer's GID: the hot path's test
        self._destroyed = False
        self._tagged = writer_tagged_subscription(node, UInt8MultiArray, schema.topic,
                                                  qos.reader_qos(schema), self._on_sample)
        if self._tagged is None:
            # Only a reader that ages records from their send asks for the message info:
            # rclpy 7.1.6's EventsExecutor fails ("SystemError: null argument") on (msg, info)
            # callbacks. rclpy's annotation has only the one-argument callback it also takes.
            self._sub = node.create_subscription(
                UInt8MultiArray, schema.topic,
                self._on_msg_info if sent_stamps else self._on_msg,  # type: ignore[arg-type]
                qos.reader_qos(schema), raw=True)
        self.watch = WriterWatch(node, self, schema.name, schema.topic)

    def destroy(self) -> None:
        """Free the subscription now, before its node is destroyed.

        The writer-tagged subscription is no subscription of the node's, so destroy_node does
        not free it; left to the garbage collector it would be finalised whenever a collection
        comes, and Fast DDS can wait for ever there (delete_datareader against its event
        thread). Its context's shutdown frees it too, at the latest.
        """
        if self._destroyed:
            return
        self._destroyed = True
        if self._tagged is not None:
            self._tagged.destroy()
        else:
            self._node.destroy_subscription(self._sub)

    def publisher_count(self) -> int:
        """Writers this reader has matched (its own side of the link)."""
        if self._tagged is not None:
            return self._tagged.publisher_count()
        return self._sub.get_publisher_count()

    def identity(self) -> str:
        """Say who this reader takes records from (its /diagnostics `writer` value)."""
        if self._tagged is None:
            return f'not checked: {writer_identity_unavailable()}'
        if self._tagged.layout_ok is False:
            return 'not checked: the message info is not laid out as in Jazzy (no GID)'
        gid = self._current.hex() if self._current else 'not heard yet'
        check = self.check
        return (f'{self.writer} ({gid}); {check.held} held for the graph, {check.restarts} '
                f'restarts, {check.duplicate_samples} from a duplicate, {check.lookups} graph '
                'queries')

    def _graph_writers(self) -> list[tuple[str, bytes]]:
        return graph_writers(self._node, self.schema.topic)

    def _on_sample(self, raw: bytes, gid: bytes | None, stamp: int) -> None:
        self.sent_ns = stamp
        if gid == self._current or gid is None:  # None: no GID to be had (check off)
            self._on_msg(raw)
            return
        for (data, sent_ns), who, verdict in self.check.admit((raw, stamp), gid):
            self.sent_ns = sent_ns  # a held sample's own
            self.duplicate = self.check.duplicate_text(self.schema.name)
            if verdict == FOREIGN_WRITER:
                self._reject(FOREIGN_WRITER, f'{self.schema.name}: from '
                             f'{self.check.name(who)} ({who.hex()}), not the '
                             f'writer {self.writer}')
                continue
            if verdict == DUPLICATE_WRITER:  # a fault: its node stops the truck
                self._current = None  # every sample judged until the duplicate ends
                if self.last_reason != DUPLICATE_WRITER:
                    self._node.get_logger().error(f'duplicate writer: {self.duplicate}')
                self._reject(DUPLICATE_WRITER, self.duplicate)
                if self.on_reject is not None:
                    self.on_reject()
                continue
            if verdict == 'restart':
                self.resync()  # a new process: its counter starts afresh
            self._current = who
            self._on_msg(data)

    def _on_msg_info(self, raw: bytes, info: Mapping[str, Any]) -> None:
        self.sent_ns = info.get('source_timestamp') or 0
        self._on_msg(raw)

    def _on_msg(self, raw: bytes) -> None:
        fields = self.accept(record_bytes(raw), self._now_ns())
        if fields is None:
            if self.on_reject is not None:
                self.on_reject()
        elif self._callback is not None:
            self._callback(fields)


# /diagnostics levels as the ints diagnostic_status takes (DiagnosticStatus has them as bytes)
OK, WARN, ERROR = (int.from_bytes(level) for level in (DiagnosticStatus.OK, DiagnosticStatus.WARN,
                                                        DiagnosticStatus.ERROR))


def diagnostic_status(node: Node, label: str, level: int, message: str, hardware_id: str,
                      values: Mapping[str, str]) -> DiagnosticStatus:
    """One /diagnostics row named `agv[/ns]/<label>` (the name agv-diag and the tests read)."""
    ns = node.get_namespace().strip('/')
    status = DiagnosticStatus(name=f'agv{"/" + ns if ns else ""}/{label}', message=message,
                              hardware_id=hardware_id)
    status.level = bytes([level])
    status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return status


class InputDiagnostics:
    """Publishes a node's record inputs on /diagnostics once a (ROS-clock) second.

    One DiagnosticStatus `agv[/ns]/<node>/inputs` (hardware_id `<node>`): accepted, rejected
    by reason, counter gaps and the last rejection per record, WARN while records are being
    rejected, and the node's own verdict when it has one (traction: the trip relay). Every node
    that reads records has it, so a malformed record is counted and shown wherever it arrives,
    and a node whose executive has gone silent still says so.
    """

    def __init__(self, node: Node, readers: Mapping[str, CountedInput], period: float = 1.0,
                 health: Callable[[], tuple[int, str]] | None = None) -> None:
        self._node = node
        self._readers = readers
        self._health = health
        self._before = 0
        self._now_ns = node_time(node)
        self._pub = node.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        periodic = getattr(node, 'periodic', None)  # a CoreNode's timers follow its executor
        if periodic is not None:
            periodic(period, self.publish)
        else:
            node.create_timer(period, self.publish)

    def add(self, name: str, port: Any) -> None:
        """Show one more input (a CheckedInput, or a reader a subclass makes after the core's)."""
        self._readers = {**self._readers, name: port}

    def publish(self) -> None:
        """Send the current counts."""
        level, message, values = inputs_report(
            self._readers, self._before, self._now_ns(),
            self._health() if self._health else None)
        self._before = sum(r.rejected for r in self._readers.values())
        name = self._node.get_name()
        msg = DiagnosticArray(status=[diagnostic_status(self._node, f'{name}/inputs', level,
                                                        message, name, values)])
        msg.header.stamp = self._node.get_clock().now().to_msg()
        self._pub.publish(msg)


LINKS_TOPIC = 'graph/links'


class LinkAnnouncer:
    """Says on `graph/links` which of a node's record links have matched, at both ends.

    Discovery is two-sided: a writer may match a reader (and the world may count it) before
    the reader has matched the writer, and a volatile reader drops what comes in meanwhile; a
    reader may match a writer before the writer has matched it, and the writer sends it
    nothing meanwhile. A run that starts then loses its first records (navigation sees a task
    before any sensor status and calls the sensor lost). So each node polls its own readers
    and writers on a steady timer (sim time stands still until the world moves) and publishes
    `"<node> rec1 rec2 ... out1>N1 out2>N2 ..."` (latched) each time it changes: the inputs that
    have matched a writer, and how many readers each output has matched. The world waits for
    the links the launcher names (`wait_for_links`) before it moves. Once every input has
    matched and the node's clock runs, polling slows to `settled_period`: under sim time the
    clock runs only once the world has moved, but on the wall clock (use_sim_time false, the
    hardware configuration) it runs from the start, and stopping there would leave the world
    waiting for readers of this node's outputs that match later (the world's pacing reader).
    """

    def __init__(self, node: Node, readers: Mapping[str, RecordSubscription],
                 writers: Mapping[str, RecordPublisher] | None = None,
                 period: float = 0.02, settled_period: float = 1.0) -> None:
        self._node = node
        self._readers = readers
        self._writers = writers or {}
        self._now_ns = node_time(node)
        self._said: str | None = None
        self._pub = node.create_publisher(String, LINKS_TOPIC, qos.LATCHED)
        self._steady = RosClock(clock_type=ClockType.STEADY_TIME)
        self._settled_period = settled_period
        self.settled = False
        self._timer = node.create_timer(period, self.poll, clock=self._steady)

    def poll(self) -> None:
        """Publish the matched links if they changed; stop once inputs match and time runs."""
        matched = {name for name, r in self._readers.items() if r.publisher_count() > 0}
        words = [self._node.get_name(), *sorted(matched),
                 *(f'{name}>{w.subscription_count}' for name, w in sorted(self._writers.items()))]
        text = ' '.join(words)
        if text != self._said:
            self._said = text
            self._pub.publish(String(data=text))
        if not self.settled and len(matched) == len(self._readers) and self._now_ns() > 0:
            self.settled = True
            self._node.destroy_timer(self._timer)
            self._timer = self._node.create_timer(self._settled_period, self.poll,
                                                  clock=self._steady)


def parse_links(text: str) -> tuple[str, set[str], dict[str, int]]:
    """Parse a LinkAnnouncer line.

    `"<node> rec1 rec2 ... out1>N1 ..."` -> (node, {inputs matched}, {output: readers
    matched}).
    """
    words = text.split()
    inputs, outputs = set(), {}
    for word in words[1:]:
        name, sep, count = word.partition('>')
        if not sep:
            inputs.add(word)
        elif count.isdigit():
            outputs[name] = int(count)
    return (words[0] if words else ''), inputs, outputs
