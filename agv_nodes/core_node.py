"""CoreNode: the one rclpy node every sub-processor is, around its ROS-free core.

`CoreNode(SomeCore)` declares the node's parameters from NodeSettings and the core's settings
dataclass (agv_nodes/settings.py: one place for every default), builds the core, creates one
RecordPublisher per record the core writes and one RecordSubscription per record it reads
(from the schemas' writer/readers: the same port declarations the lock-step harness uses),
feeds accepted records and rejections to the core, runs its timer on the ROS clock, takes
hw/radio_stop for cores that read it, logs the core's notes, and publishes what it returns.
With `sim_progress` (a simulated world) it also says how far it has got (agv_nodes/sim_progress).
Under sim time a wall-clock watch says on /diagnostics when /clock stops (agv_nodes/clock_watch).
Under sim time with the EventsExecutor, /clock is taken from its one writer only (`clock_writer`),
and a jump of that writer's clock is a fault the core is told of (agv_nodes/clock_jump.py).
"""

from __future__ import annotations

from collections.abc import Callable
import random
from typing import Any, Generic, TypeVar

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from agv_nodes import qos, sim_progress
from agv_nodes.clock_jump import ClockJumpRule, Jump
from agv_nodes.clock_watch import ClockWatch
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.rclpy_internals import drop_clock_reader, writer_tagged_subscription
from agv_nodes.records import codec
from agv_nodes.records.carrier import clock_cdr
from agv_nodes.records.ports import WriterCheck
from agv_nodes.ros_ports import (
    InputDiagnostics,
    LinkAnnouncer,
    RecordPublisher,
    RecordSubscription,
    clock_time_ns,
    full_name,
)
from agv_nodes.settings import NodeSettings
from agv_nodes.stop_switches import switch_inputs
from agv_nodes.subsystem import SubsystemCore

__all__ = ['ClockTimers', 'CoreNode', 'SimProgress', 'spin_main']


CoreT = TypeVar('CoreT', bound=SubsystemCore)  # a node's core (executive/core.py's, ...)


class SimProgress:
    """Publishes sim/progress/<node>: the latest sim time the node has handled (raw Clock)."""

    def __init__(self, node: Node) -> None:
        self._pub = node.create_publisher(Clock, sim_progress.topic(node.get_name()),
                                          qos.PROGRESS)
        self._period = round(sim_progress.PERIOD * 1e9)
        self._next = 0

    @property
    def subscription_count(self) -> int:
        """Readers matched (the world's)."""
        return self._pub.get_subscription_count()

    def handled(self, now_ns: int) -> None:
        """Every input up to `now_ns` (a /clock just taken) has been handled."""
        if now_ns >= self._next or now_ns < self._next - 10 * self._period:
            self._next = now_ns + self._period
            self._pub.publish(clock_cdr(now_ns))


class CoreNode(Node, Generic[CoreT]):
    """A node around one core (see the module docstring).

    Subclasses add what a node has besides its records (camera frames, text topics,
    /diagnostics).
    """

    sent_stamps = False  # (msg, info) readers: see RecordSubscription

    def __init__(self, core_type: type[CoreT], name: str | None = None) -> None:
        super().__init__(name or core_type.node)
        self.node_settings = declare(self, NodeSettings)
        self.core: CoreT = core_type(declare(self, core_type.settings_type))
        self.extend()
        refuse_unknown(self)
        self.executor_kind = self.node_settings.executor
        self._clock_timers: ClockTimers | None = None
        sim_time = self.get_parameter('use_sim_time').value
        progress = SimProgress(self) if self.node_settings.sim_progress and sim_time else None
        if self.executor_kind == 'events' and sim_time:
            self._clock_timers = ClockTimers(self, progress,
                                             full_name(self, self.node_settings.clock_writer),
                                             self.node_settings.clock_jump_limit, self._jumped)
        elif progress is not None:  # rclpy's timers: a /clock reader only for the progress
            def on_clock(raw: bytes) -> None:
                progress.handled(clock_time_ns(raw))
            self.create_subscription(Clock, '/clock', on_clock, qos.CLOCK_READER, raw=True)
        self._attach(progress)

    def extend(self) -> None:
        """Declare what a subclass needs besides the core's settings.

        Called before the check for parameters nobody declared.
        """

    def _attach(self, progress: SimProgress | None) -> None:
        ns = self.node_settings
        integrity = ns.record_integrity
        reads, writes = codec().for_node(self.core.node)
        # Fault injection (agv-launch --fault): one of this node's records is lost or delayed
        # on its way out, as a bad link would. The E2E counter still advances for a lost
        # record, so readers see the gap (counted as lost in /diagnostics).
        if ns.fault_record and ns.fault_record not in {s.name for s in writes}:
            raise parameter_error(self, 'fault_record', ns.fault_record, 'not a record this '
                                  f'node writes ({", ".join(s.name for s in writes)})')
        self._fault_rng = random.Random(ns.fault_seed)
        self._held: list[tuple[float, bytes]] = []
        self.writers = {s.name: RecordPublisher(self, s, integrity) for s in writes}
        self.readers = {s.name: RecordSubscription(self, s, integrity,
                                                   callback=self._on_record(s.name),
                                                   sent_stamps=self.sent_stamps)
                        for s in reads}
        for reader in self.readers.values():
            reader.on_reject = self._on_reject(reader)
        outputs: dict[str, Any] = dict(self.writers)
        if progress is not None:
            outputs[sim_progress.LINK] = progress
        # the world moves once every link has matched at both ends
        self.links = LinkAnnouncer(self, self.readers, outputs)
        # hw/radio_stop, hw/bumper: each from its named writer (agv_nodes/stop_switches.py)
        self.switches = switch_inputs(self)
        if self.core.period:
            self.periodic(self.core.period, self._tick)
        if self.core.supervision_period:
            self.periodic(self.core.supervision_period,
                          lambda: self.publish(self.core.supervise(self.now_s())))
        if ns.fault_record and ns.fault_delay:
            self.periodic(0.001, self._release)  # fires once per /clock step
        if ns.fault_record:
            self.add_on_set_parameters_callback(self._set_fault)
        self.input_diagnostics = InputDiagnostics(self, {**self.readers, **self.switches},
                                                  health=getattr(self.core, 'health', None))
        if self.get_parameter('use_sim_time').value:
            self.clock_watch = ClockWatch(self)

    def periodic(self, period: float, callback: Callable[[], None]) -> None:
        """Call `callback` every `period` s of ROS time, as a rclpy timer would.

        Under sim time with the EventsExecutor the time comes from the node's own /clock
        reader (see ClockTimers).
        """
        if self._clock_timers is not None:
            self._clock_timers.add(period, callback)
        else:
            self.create_timer(period, callback)

    def ros_now_s(self) -> float:
        """Return the ROS time in seconds (sim time when use_sim_time is set).

        Under the EventsExecutor it is the latest /clock taken in arrival order (ClockTimers),
        else the ROS clock.
        """
        if self._clock_timers is not None and self._clock_timers.now_ns is not None:
            return self._clock_timers.now_ns * 1e-9
        return self.get_clock().now().nanoseconds * 1e-9

    def now_s(self) -> float:
        """Return the core's time: ros_now_s (the executive may age records otherwise)."""
        return self.ros_now_s()

    def _on_record(self, name: str) -> Callable[[dict[str, Any]], None]:
        def callback(fields: dict[str, Any]) -> None:
            now = self.now_s()
            if self.readers[name].restarted:
                self.publish(self.core.on_writer_restart(name, now))
            self.publish(self.core.on_record(name, fields, now))
        return callback

    def _on_reject(self, reader: RecordSubscription) -> Callable[[], None]:
        def callback() -> None:
            handler = getattr(self.core, 'on_reject', None)
            if handler is not None:
                self.publish(handler(reader.schema.name, reader.last_reason, self.now_s()))
        return callback

    def _jumped(self, jump: Jump) -> None:
        """Say that the genuine /clock jumped and tell the core (the executive fails the task)."""
        timers = self._clock_timers  # the one that calls this
        writer = timers.writer if timers is not None else self.node_settings.clock_writer
        self.get_logger().error(f'{jump.text()} (/clock from {writer}): '
                                'a fault of the clock, not of any input')
        handler = getattr(self.core, 'on_clock_jump', None)
        if handler is not None:
            self.publish(handler(jump.text(), self.now_s()))

    def _tick(self) -> None:
        self.publish(self.core.tick(self.now_s()))

    def say(self, text: str, level: str) -> None:
        """Log one of the core's notes.

        One call site per severity: rclpy keys a log call's settings on where it is made and
        raises if one site logs at two severities.
        """
        logger = self.get_logger()
        if level == 'warn':
            logger.warning(text)
        else:
            logger.info(text)

    def publish(self, outputs: dict[str, dict[str, Any]] | None) -> None:
        """Publish the records a core returned (and what it noted, in words)."""
        notes = getattr(self.core, 'notes', None)
        if notes is not None:
            for note in notes.take():
                self.say(note.text, note.level)
        for record, fields in (outputs or {}).items():
            if record == self.node_settings.fault_record:
                self._faulty(record, fields)
            else:
                self.writers[record].publish(fields)

    def _faulty(self, record: str, fields: dict[str, Any]) -> None:
        raw = self.writers[record].pack(fields)
        if self._fault_rng.random() < self.node_settings.fault_loss:
            return  # lost on the way
        corrupt = self.node_settings.fault_corrupt
        if corrupt and self._fault_rng.random() < corrupt:
            raw = bytes((raw[0] ^ 0x01,)) + raw[1:]  # byte 1 hit: the CRC no longer fits
        if self.node_settings.fault_delay:
            self._held.append((self.now_s() + self.node_settings.fault_delay, raw))
        else:
            self.writers[record].publish_raw(raw)

    def _set_fault(self, params: list[Parameter]) -> SetParametersResult:
        # the descriptor's range has checked the value; the others are read-only
        for p in params:
            if p.name == 'fault_corrupt':
                self.node_settings.fault_corrupt = float(p.value)
        return SetParametersResult(successful=True)

    def _release(self) -> None:
        now = self.now_s()
        while self._held and self._held[0][0] <= now:
            self.writers[self.node_settings.fault_record].publish_raw(self._held.pop(0)[1])


class ClockTimers:
    """A node's sim time and periodic callbacks under the EventsExecutor.

    They come from the node's own FIFO /clock reader. The EventsExecutor takes every input in
    the order it arrived. The ROS clock's own /clock reader keeps only the newest sample, so in
    a process that has fallen behind it runs ahead of the records still queued, and a record
    taken late looks late (a false "sensor lost" when the graph runs faster than the machine
    keeps up with). Read FIFO, /clock is one more input in the queue:
    each record is handled at the sim time it arrived, and a starved node blames nobody. The
    callbacks follow rclpy timer semantics under sim time: due every `period` s, at most once
    per /clock message, periods a jump passed over are skipped. After them, the node's
    progress (if it reports one) moves to this /clock.

    /clock has one writer, the node `writer` (full name): each sample is taken with its
    writer's GID (rclpy_internals.WriterTaggedSubscription) and judged by records.ports
    WriterCheck, as a record reader's are. A sample from any other endpoint is rejected
    (counted by reason in `rejects`, named in `last_rejection`) and never moves the node's time.
    The genuine writer's samples go through the clock-jump rule (agv_nodes/clock_jump.py): a
    jump is absorbed (the node's time runs on from where it stood) and `on_jump` is told.
    `check_writer` False takes every sample (a test's stand-in node, which has no DDS handle).
    """

    def __init__(self, node: Node, progress: SimProgress | None = None, writer: str = '/world',
                 jump_limit: float = 0.1, on_jump: Callable[[Jump], None] | None = None,
                 check_writer: bool = True) -> None:
        self.now_ns: int | None = None  # the node's time at the latest /clock taken
        self._timers: list[list[Any]] = []  # [period, next due (ns) or None, callback]
        self._progress = progress
        self.writer = writer
        self.rule = ClockJumpRule(jump_limit)
        self._on_jump = on_jump
        self.accepted = 0
        self.rejects: dict[str, int] = {}  # reason -> samples rejected
        self.last_rejection = ''
        # One /clock reader per node, not two: taking every sample twice cost an idle node
        # 3.9 % of a core against 2.7 % at 113 Hz (bench/rclpy_bench.py). This one sets the
        # node's ROS clock, so get_clock() is the same FIFO time.
        self._time_source = drop_clock_reader(node)
        # Taken serialized: at 116 Hz in every node, rclpy's conversion to a Clock message cost
        # more than the take itself (bench/rclpy_bench.py: 335 -> 237 us a message at 340 Hz).
        self._msg = Clock()  # one message, re-filled for the TimeSource
        self._node = node
        self.check = WriterCheck(writer, self._graph_writers)
        self._current: bytes | None = None  # the genuine writer's GID: the hot path's test
        self._tagged = writer_tagged_subscription(node, Clock, '/clock', qos.CLOCK_READER,
                                                  self._on_sample) if check_writer else None
        if self._tagged is None:  # no GID to be had (said on stderr): every sample is taken
            node.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK_READER, raw=True)

    def add(self, period: float, callback: Callable[[], None]) -> None:
        """One more periodic callback."""
        self._timers.append([round(period * 1e9), None, callback])

    @property
    def identity(self) -> str:
        """Say whose /clock this node takes (its /diagnostics `clock writer` value)."""
        if self._tagged is None:
            return f'{self.writer} (not checked: no writer identity here)'
        gid = self._current.hex() if self._current else 'not heard yet'
        return f'{self.writer} ({gid})'

    def _graph_writers(self) -> list[tuple[str, bytes]]:
        return [(f'{i.node_namespace.rstrip("/")}/{i.node_name}', bytes(i.endpoint_gid))
                for i in self._node.get_publishers_info_by_topic('/clock')]

    def _on_sample(self, raw: bytes, gid: bytes | None, _stamp: int) -> None:
        sequence = self._tagged.sequence  # type: ignore[union-attr]
        if gid == self._current or gid is None:  # None: no GID to be had (check off)
            self._on_clock(raw, sequence)
            return
        for (data, seq), who, verdict in self.check.admit((raw, sequence), gid):
            if verdict not in ('genuine', 'restart'):  # foreign_writer, duplicate_writer
                self.rejects[verdict] = self.rejects.get(verdict, 0) + 1
                self.last_rejection = (f'/clock at {clock_time_ns(data) * 1e-9:.3f} s from '
                                       f'{self.check.nodes.get(who, "?")} ({who.hex()}): '
                                       f'{verdict}, not the writer {self.writer}')
                continue
            if verdict == 'restart':
                self.rule.restart()  # a new process: its sequence numbers start afresh
            self._current = who
            self._on_clock(data, seq)

    def _on_clock(self, raw: bytes, sequence: int = 0) -> None:
        writer_ns = clock_time_ns(raw)
        if writer_ns <= 0:
            return  # the world's clock has not started
        self.accepted += 1
        now = self.rule.take(writer_ns, sequence)
        self.now_ns = now
        if self._time_source is not None:
            self._msg.clock.sec, self._msg.clock.nanosec = divmod(now, 1_000_000_000)
            self._time_source.clock_callback(self._msg)
        if self.rule.jump is not None and self._on_jump is not None:
            self._on_jump(self.rule.jump)  # before any timer: the fault is the jump's
        for timer in self._timers:
            period, due, callback = timer
            if due is None or now < due - 10 * period:  # first tick, or sim time went back
                timer[1] = now + period
                continue
            if now >= due:
                skipped = (now - due) // period
                timer[1] = due + (skipped + 1) * period
                callback()
        if self._progress is not None:
            self._progress.handled(now)
