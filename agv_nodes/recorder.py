"""recorder: writes every topic of the graph to a rosbag2 bag (ros2 run agv_nodes recorder).

Where ros2 bag is not installed (PyPI-only machines), this node does what `ros2 bag record -a -s
mcap` does for this graph: it discovers topics as they appear (or takes a fixed list),
subscribes with raw=True so the serialized CDR goes to disk untouched, and writes a rosbag2
bag - metadata version 9, MCAP storage, with each topic's offered QoS profiles - through
`rosbags`. Timestamps are the node's ROS time (sim time under use_sim_time). Each subscription
asks for the publishers' reliability and, when they all offer it, transient-local durability
(so latched topics like world/route are caught). When a bag passes `max_bag_size` bytes it is
closed and recording continues in `<bag>_1`, `<bag>_2`, ... (each a complete bag). The bag is
closed cleanly on SIGINT/SIGTERM, and is readable at any moment before that: twice a second of
wall time (`CHECKPOINT`) what has been written is committed to the file with its index and
footer (CommittedFile), and metadata.yaml is rewritten every few seconds, so a SIGKILLed
recorder leaves a bag that rosbags and mcap read up to its last second (a power cut may lose
what the operating system had not yet written out: there is no fsync).

A full disk (any OSError writing the bag: ENOSPC, or `space_limit` reached, which raises the
same) stops the recording, not the recorder: the bag file is put back as its last commit left
it (bag_file.CommittedFile), the error is logged, and /diagnostics says why (row
`agv[/ns]/recorder/bag`, ERROR) until the end. The recorder goes on taking what the graph sends,
counted as not recorded, so that nothing the truck's nodes see changes: the launcher ends a run
whose node dies, and a reader that stopped taking would be another reader than the one matched.

What a person reads (`views`, default on; agv_nodes/view/bag_views.py): every record the bag
gets is also decoded, with its reader's verdict, as JSON into `decoded.mcap` in the bag's
directory, and the trucks' frames, from the world's pose and the wheel odometry, go into the bag
itself as `/tf` and `/tf_static` (tf2_msgs, which rosbags knows, so every bag has them).

Polling (`poll_period`, default 20 ms of wall time): the recorder's subscriptions sit in a
callback group the executor never waits on, and a steady timer takes everything queued on
every topic at once. A callback per message cost the recorder ~45 % of a core at real time
(bench/graph_bench.py: ~1,200 messages/s, each an executor turn over ~30 subscriptions); one
turn per 20 ms serves them all. Each message is then stamped with the sim time at which it was
*sent* (its DDS source timestamp placed on the recorded /clock, agv_nodes.sent_time) rather
than when the recorder got round to it. `poll_period: 0` keeps a callback per message, stamped
on arrival.
"""

from __future__ import annotations

import importlib
from pathlib import Path
import sys
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from agv_nodes import qos
from agv_nodes.bag_file import CommittedFile, to_bag_qos
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.rclpy_internals import drop_clock_reader, take_all
from agv_nodes.ros_ports import LINKS_TOPIC, clock_time_ns, diagnostic_status
from agv_nodes.sent_time import SentTimeline
from agv_nodes.settings import settings_class
from agv_nodes.sim_progress import CLOCK_LINK

SKIP = {'/parameter_events'}
# s of wall time between commits of the bag file and its metadata.yaml: half the second a
# kill may lose, for a late timer or poll. Each commit rewrites the summary, which grows by one
# chunk index per commit (~0.4 kB with 39 topics: 2.9 MB after an hour; max_bag_size bounds it).
CHECKPOINT = 0.5
# Checkpoints between rewrites of metadata.yaml (and at every new topic): rosbags dumps it with
# ruamel.yaml, 30 ms for the demo's 39 topics (the MCAP index takes under 1 ms). A killed bag's
# metadata.yaml may thus count up to 5 s fewer messages than its MCAP file, which a reader
# reads to the end anyway (its index is exact).
METADATA_EVERY = 10


@settings_class
class RecorderSettings:
    """The recorder's parameters."""


def message_class(type_name: str) -> Any:
    """'std_msgs/msg/UInt8MultiArray' -> the rclpy message class."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


class PolledGroup(CallbackGroup):
    """Entities the executor never waits on or runs: their owner takes their messages."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


class Recorder(Node):
    """See the module docstring."""

    def __init__(self) -> None:
        super().__init__('recorder')
        s = declare(self, RecorderSettings)
        refuse_unknown(self)
        self.bag_path = Path(s.bag)
        self.topics = list(s.topics)
        self.max_size = s.max_bag_size
        self.all_namespaces = s.all_namespaces
        self.poll_period = s.poll_period
        self.space_limit = s.space_limit
        if self.bag_path.exists():
            raise parameter_error(self, 'bag', s.bag, 'exists already (a bag is never '
                                  'overwritten)')
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.part = 0
        self.writer: Writer | None = None
        self.connections: dict[str, Any] = {}
        self.types: dict[str, str] = {}
        self.subs: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self._offered: dict[str, list[Qos]] = {}
        self.bytes = 0
        self.paths: list[Path] = []
        self.written = 0  # messages written to the bag (committed at the next checkpoint)
        self.committed = 0  # messages in the bag file as its last commit left it
        self.unrecorded = 0  # messages taken after recording stopped
        self.stopped = ''  # why recording stopped ('' while it runs)
        self._closed = False
        self.views: Any = None  # decoded records and frames (`views`), once the bag is open
        self.timeline = SentTimeline(keep=10.0)
        self.hold = 2.0  # s of wall time a message may wait for the /clock samples that place it
        self._held: list[tuple[int, str, bytes, int]] = []  # (sent ns, topic, raw, held since)
        self._polled = PolledGroup() if self.poll_period else None
        self._time_source_fed: Any = None  # rclpy's TimeSource, fed from the polled /clock
        self._clock_msg = Clock()  # re-filled from each /clock sample's CDR
        # metadata.yaml as last written: (topics, checkpoints since, the text rosbags made)
        self._metadata: tuple[int, int, str] = (0, 0, '')
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.EVENTS)
        try:
            self._open()
        except OSError as exc:
            self._stop(exc)
        self.views = self._views(s) if s.views and self.writer is not None else None
        # 'recorder clock' on graph/links once /clock is matched: the world does not move
        # before (its wait list has 'recorder:clock'), so the bag has every /clock sample
        self._links = self.create_publisher(String, LINKS_TOPIC, qos.LATCHED)
        self._clock_said = False
        self.create_timer(0.5, self._discover, clock=self._wall_clock())
        if self.poll_period:
            self.create_timer(self.poll_period, self.poll, clock=self._wall_clock())
        self.create_timer(CHECKPOINT, self.checkpoint, clock=self._wall_clock())
        self.create_timer(1.0, self.diagnostics, clock=self._wall_clock())
        self.add_on_set_parameters_callback(self._set_space_limit)
        self._discover()

    def _views(self, s: Any) -> Any:
        """Return the bag's decoded records and frames (agv_nodes/view/bag_views.py)."""
        from agv_nodes.view.bag_views import BagViews
        from agv_nodes.view.frames import track_of, truck_shape
        from agv_nodes.world.layout import LayoutError, layout_path, load_layout
        from agv_nodes.world.settings import WorldParams

        try:
            layout = load_layout(layout_path(s.layout))
        except (LayoutError, OSError) as exc:
            raise parameter_error(self, 'layout', s.layout, str(exc)) from None
        world = WorldParams()
        shape = truck_shape(layout.vehicle, layout.sensor_lateral, world)
        return BagViews(self.bag_path, shape, track_of(shape, world), s.record_integrity)

    def _wall_clock(self):
        from rclpy.clock import Clock, ClockType

        return Clock(clock_type=ClockType.STEADY_TIME)

    def _open(self) -> None:
        path = self.bag_path if self.part == 0 else \
            self.bag_path.with_name(f'{self.bag_path.name}_{self.part}')
        self.paths.append(path)
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.set_custom_data('recorded_by', 'agv_nodes recorder')
        self.writer.open()
        self.connections = {}
        self.bytes = 0
        storage: Any = getattr(self.writer, 'storage', None)  # rosbags' untyped internals
        if hasattr(storage, 'bio') and hasattr(storage, 'close_chunk'):
            storage.bio = CommittedFile(storage.bio, self.space_limit)
            self.checkpoint(force=True)
        else:  # another rosbags: the bag is readable only once closed
            self.get_logger().warn('rosbags writer without checkpoints: a killed recorder '
                                   'leaves an unreadable bag')

    def checkpoint(self, force: bool = False) -> None:
        """Commit what is written to the bag file, indexed (and now and then metadata.yaml).

        The open chunk is closed (rosbags starts another) and rosbags' storage close runs on a
        CommittedFile marked for a checkpoint: it writes the summary and footer, and the file
        stays open for more. For metadata.yaml the whole Writer.close() runs (METADATA_EVERY),
        and the metadata text it hands the storage is kept for the checkpoints between.
        Nothing new since the last one: nothing to do. A failed write stops the recording.
        """
        try:
            self._checkpoint(force)
        except OSError as exc:
            self._stop(exc)

    def _checkpoint(self, force: bool) -> None:
        writer = self.writer
        # rosbags' MCAP storage: its file, chunk and close are beyond the typed StorageProtocol
        storage: Any = getattr(writer, 'storage', None)
        bag_file = getattr(storage, 'bio', None)
        if writer is None or not isinstance(bag_file, CommittedFile):
            return
        if storage.chunk.bio.tell():
            storage.close_chunk()
        if not (force or bag_file.has_new_data):
            return
        bag_file.mark()
        topics = len(writer.connections)
        if force or topics != self._metadata[0] or self._metadata[1] >= METADATA_EVERY:
            close = storage.close

            def keep(version: int, metadata: str) -> None:
                self._metadata = (topics, 0, metadata)
                close(version, metadata)
            storage.close = keep
            try:
                writer.close()
            finally:
                del storage.close  # the class's own again
                writer.storage = storage
        else:
            self._metadata = (topics, self._metadata[1] + 1, self._metadata[2])
            storage.close(writer.version, self._metadata[2])
        self.committed = self.written

    def _stop(self, exc: OSError) -> None:
        """Stop recording after a failed write: say why, keep the bag as last committed."""
        storage = getattr(self.writer, 'storage', None)
        bag_file = getattr(storage, 'bio', None)
        self.writer = None
        path = self.paths[-1] if self.paths else self.bag_path
        try:
            if isinstance(bag_file, CommittedFile):
                bag_file.abandon()
            (path / 'metadata.yaml.tmp').unlink(missing_ok=True)  # a partial one: room freed
        except OSError:
            pass
        self.stopped = (f'recording stopped: {exc.strerror or exc} writing {path}; the bag '
                        f'reads to its last commit ({self.committed} messages in all); the truck '
                        'runs on')
        self.get_logger().error(self.stopped)
        self.diagnostics()

    def _set_space_limit(self, params: list[Parameter]) -> SetParametersResult:
        # the descriptor's range has checked it; the other parameters are read-only
        for p in params:
            if p.name == 'space_limit':
                self.space_limit = int(p.value)
                bag_file = getattr(getattr(self.writer, 'storage', None), 'bio', None)
                if isinstance(bag_file, CommittedFile):
                    bag_file.space_limit = self.space_limit
        return SetParametersResult(successful=True)

    def diagnostics(self) -> None:
        """Publish the recording's state on /diagnostics (ERROR once it has stopped)."""
        values = {'messages written': str(self.written),
                  'messages committed': str(self.committed),
                  'messages not recorded': str(self.unrecorded),
                  'bag': ', '.join(map(str, self.paths)), 'space_limit': str(self.space_limit)}
        level, message = (2, self.stopped) if self.stopped else \
            (0, f'recording: {self.written} messages')
        name = self.get_name()
        msg = DiagnosticArray(status=[diagnostic_status(self, f'{name}/bag', level, message,
                                                        name, values)])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(msg)

    def _wanted(self, topic: str) -> bool:
        if topic in SKIP or self.views is not None and topic in ('/tf', '/tf_static'):
            return False  # with views, the bag's frames are the recorder's own
        if self.topics:
            return topic in self.topics or topic.lstrip('/') in self.topics
        ns = self.get_namespace().rstrip('/')
        if self.all_namespaces or not ns:
            return True
        return topic.startswith(ns + '/') or topic.count('/') == 1  # own namespace or global

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subs or not types or not self._wanted(topic):
                continue
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            type_name = types[0]
            try:
                cls = message_class(type_name)
                self.typestore.types[type_name]  # noqa: B018 - the bag needs its definition
            except (ImportError, AttributeError, KeyError, ValueError):
                self.get_logger().warn(f'not recording {topic}: type {type_name} unknown')
                self.subs[topic] = None
                continue
            offered = [i.qos_profile for i in infos]
            reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
            latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
            # deep enough for ~2 s of the 340 Hz ADC stream at 3x real time: a poll delayed by
            # a bag flush or a CPU-starved turn must not let the queue overflow
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2000,
                             reliability=ReliabilityPolicy.RELIABLE if reliable
                             else ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                             else DurabilityPolicy.VOLATILE)
            self.types[topic] = type_name
            self._offered[topic] = [to_bag_qos(q) for q in offered]
            self.subs[topic] = self.create_subscription(
                cls, topic, self._callback(topic), qos, raw=True,
                callback_group=self._polled)
            self.counts[topic] = 0
            if topic == '/clock' and self._polled is not None:
                self._take_over_clock()
        clock = self.subs.get('/clock')
        if clock is not None and not self._clock_said and clock.get_publisher_count() > 0:
            self._links.publish(String(data=f'{self.get_name()} {CLOCK_LINK}'))
            self._clock_said = True

    def _take_over_clock(self) -> None:
        """Set the node's ROS time from the polled /clock samples; drop rclpy's own reader.

        As core_node.ClockTimers does, the /clock samples polled for the bag set the time, and
        rclpy's own /clock reader goes. That reader is the only subscription the executor waits
        on: it woke the recorder at every /clock sample (116 Hz of sim time) for one wait-set
        turn over every entity, and half the recorder's CPU went to such turns in a profile of
        the demo (py-spy), against 50 turns a second for the polls. Without it the recorder
        took 14.4 % of a core at real time instead of 21.2 (bench/graph_bench.py). Without the
        attributes (another rclpy), both stay.
        """
        if self.get_parameter('use_sim_time').value:
            self._time_source_fed = drop_clock_reader(self)

    def _connection(self, writer: Writer, topic: str) -> Any:
        conn = self.connections.get(topic)
        if conn is None:
            conn = writer.add_connection(topic, self.types[topic], typestore=self.typestore,
                                              offered_qos_profiles=self._offered[topic])
            self.connections[topic] = conn
        return conn

    def _callback(self, topic: str):
        def write(raw: bytes) -> None:
            self._write(topic, raw)
            # Drain what else is queued on this topic now: one executor wake-up (and one
            # wait-set rebuild) then serves a whole burst instead of a single message.
            for raw, _info in take_all(self.subs[topic], 200):
                self._write(topic, raw)
        return write

    def poll(self) -> None:
        """Take and write everything queued.

        /clock first, so that every message can be placed on sim time by its send. A message
        sent after the latest /clock sample taken waits (at most `hold` s of wall time) for the
        samples that place it: a /clock packet lost holds back
        every later sample until reliability repairs it, and a message stamped meanwhile with
        the last sim time known would leave 0.3-0.6 s gaps in the bag (all the ADC snapshots of
        that stretch on one stamp).
        """
        sim_time = self.get_parameter('use_sim_time').value
        ordered = sorted(self.subs, key=lambda topic: topic != '/clock')
        for topic in ordered:
            sub = self.subs[topic]
            if sub is None:
                continue
            for raw, info in take_all(sub, 1000):
                sent_ns = info.get('source_timestamp') or 0
                if topic == '/clock':
                    ns = clock_time_ns(raw)
                    self.timeline.clock(sent_ns, ns * 1e-9)
                    if self._time_source_fed is not None:
                        clock = self._clock_msg
                        clock.clock.sec, clock.clock.nanosec = divmod(ns, 1_000_000_000)
                        self._time_source_fed.clock_callback(clock)
                if not sim_time:
                    self._write(topic, raw, sent_ns)
                elif not self.timeline:  # not recording /clock: the latest sim time known
                    self._write(topic, raw, None)
                else:
                    self._held.append((sent_ns, topic, raw, time.monotonic_ns()))
        self._release(final=False)

    def _release(self, final: bool) -> None:
        """Write the held messages that the clock samples taken place.

        All of them when `final`, and any held longer than `hold` (a world that stopped
        publishing /clock).
        """
        if not self._held:
            return
        latest = self.timeline.latest_ns()
        overdue = time.monotonic_ns() - round(self.hold * 1e9)
        keep = []
        for held in self._held:
            sent_ns, topic, raw, since = held
            if final or sent_ns <= latest or since < overdue:
                stamp = max(0, round(self.timeline.sim_at(sent_ns) * 1e9))  # latched: >= 0
                self._write(topic, raw, stamp)
            else:
                keep.append(held)
        self._held = keep

    def _write(self, topic: str, raw: bytes, stamp: int | None = None) -> None:
        if self.writer is not None and self.max_size and self.bytes > self.max_size:
            try:
                self.writer.close()
                self.part += 1
                self._open()
            except OSError as exc:
                self._stop(exc)
        if self.writer is None:
            self.unrecorded += bool(self.stopped)
            return
        if stamp is None:
            stamp = self.get_clock().now().nanoseconds
        self.writer.write(self._connection(self.writer, topic), stamp, raw)
        self.bytes += len(raw)
        self.counts[topic] += 1
        self.written += 1
        if self.views is not None:
            self._write_views(self.writer, topic, raw, stamp)

    def _write_views(self, writer: Writer, topic: str, raw: bytes, stamp: int) -> None:
        """Decode a record into decoded.mcap; put the frames it moves into the bag."""
        try:
            added = self.views.take(topic, raw, stamp)
        except OSError as exc:  # decoded.mcap's disk is full: the bag itself goes on
            self.get_logger().error(f'decoded records stopped: {exc}')
            self.views = None
            return
        for extra, type_name, data in added:
            if extra not in self.types:
                self.types[extra] = type_name
                self._offered[extra] = [to_bag_qos(qos.LATCHED if extra == '/tf_static'
                                                   else qos.EVENTS)]
                self.counts.setdefault(extra, 0)
            writer.write(self._connection(writer, extra), stamp, data)
            self.bytes += len(data)
            self.counts[extra] += 1
            self.written += 1

    def close(self) -> None:
        """Write the metadata and close the bag (idempotent)."""
        if self.writer is not None and self.poll_period:
            try:
                self.poll()  # what arrived since the last turn
            except Exception:  # noqa: BLE001 - the context may be shut down already
                pass
            self._release(final=True)
        if self.writer is not None:
            try:
                self.writer.close()
                self.committed = self.written
            except OSError as exc:
                self._stop(exc)
            self.writer = None
        if self.views is not None:
            try:
                self.views.close()
            except OSError as exc:
                print(f'decoded records not finished: {exc}', flush=True)
            self.views = None
        if self._closed:
            return
        self._closed = True
        # print, not the logger: at shutdown the context (and /rosout) may be gone
        if self.stopped:
            print(f'bag closed early: {self.stopped}; {self.unrecorded} messages taken after '
                  'were not recorded', flush=True)
        else:
            print(f'bag closed: {self.written} messages on {len(self.counts)} topics in '
                  f'{", ".join(map(str, self.paths))}', flush=True)

    def finish(self) -> None:
        """Close the bag while the node is whole (the spin has ended, spin_main)."""
        self.close()

    def destroy_node(self) -> None:
        """Close the bag before the node goes."""
        self.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes recorder [--ros-args -p bag:=DIR ...]."""
    return spin_main(Recorder, args, executor=SingleThreadedExecutor)


if __name__ == '__main__':
    sys.exit(main())
