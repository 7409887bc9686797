"""CoreNode: the thin rclpy wrapper every sub-processor node is made of.

It creates one RecordPublisher per record the core writes and one RecordSubscription per record
it reads, both from the schemas' writer/readers (the same port declarations the lock-step
harness uses), feeds accepted records and rejections to the core, runs the core's timer on the
ROS clock (sim time under use_sim_time), subscribes hw/radio_stop for cores that want it, and
publishes whatever the core returns.
"""

from __future__ import annotations

from collections.abc import Callable
import faulthandler
import gc
import os
import random
import signal
import sys
import threading
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool

from agv_nodes import qos
from agv_nodes.params import ParameterError, Parameters
from agv_nodes.records import codec
from agv_nodes.ros_ports import (
    InputDiagnostics,
    LinkAnnouncer,
    RecordPublisher,
    RecordSubscription,
    clock_time_ns,
)


class CoreNode(Node):
    """A node around one core; subclasses declare parameters and build the core."""

    # Readers keep each record's DDS source timestamp: (msg, info) callbacks, which rclpy
    # 7.1.6's EventsExecutor cannot run, so only a `single` node may set it (the executive).
    sent_stamps = False
    executor_kind = 'single'  # the `executor` parameter (attach declares it)
    _clock_timers: ClockTimers | None = None

    def attach(self, core: Any, params: Parameters) -> None:
        """Declare record_integrity, then create the core's ports and timer."""
        integrity = params.choice('record_integrity', 'e2e', 'end-to-end protection of the '
                                  'inter-processor records (none: a legacy peer sending plain '
                                  'thesis records)', ('e2e', 'none'))
        self.core = core
        self._warnings: list[str] = getattr(core, 'warnings', [])  # the core's notes to log
        if not self.has_parameter('executor'):  # (the executive declares it earlier)
            self.executor_kind = declare_executor(params)
        if self.executor_kind == 'events' and self.get_parameter('use_sim_time').value:
            self._clock_timers = ClockTimers(self)
        reads, writes = codec().for_node(core.node)
        # Fault injection (agv-launch --fault; issue 9): one of this node's records is lost
        # or delayed on its way out, as a bad link would. The E2E counter still advances for a
        # lost record, so readers see the gap (counted as lost in /diagnostics).
        self.fault_record = params.choice('fault_record', '', 'inject faults into this '
                                          'record on its way out (empty: none)',
                                          ('', *(w.name for w in writes)))
        self.fault_loss = params.number('fault_loss', 0.0, 'fraction of fault_record records '
                                        'dropped', 0.0, 1.0)
        self.fault_delay = params.number('fault_delay', 0.0, 'extra delay of fault_record '
                                         'records, s (released on the next /clock step)',
                                         0.0, 1.0)
        self._fault_rng = random.Random(params.integer('fault_seed', 1, 'seed of the losses',
                                                       0, 2**31 - 1))
        self._held: list[tuple[float, bytes]] = []
        self.writers = {s.name: RecordPublisher(self, s, integrity) for s in writes}
        self.readers = {s.name: RecordSubscription(self, s, integrity,
                                                   callback=self._on_record(s.name),
                                                   sent_stamps=self.sent_stamps)
                        for s in reads}
        for reader in self.readers.values():
            reader.on_reject = self._on_reject(reader)
        # the world moves once every link has matched at both ends
        self.links = LinkAnnouncer(self, self.readers, self.writers)
        if hasattr(core, 'on_radio_stop'):
            self.create_subscription(Bool, 'hw/radio_stop', self._radio_stop,
                                     qos.RECORD_READER)
        if core.period:
            self.periodic(core.period, self._tick)
        if self.fault_record and self.fault_delay:
            self.periodic(0.001, self._release)  # fires once per /clock step
        self.input_diagnostics = InputDiagnostics(self, self.readers,
                                                  health=getattr(core, 'health', None))

    def periodic(self, period: float, callback: Callable[[], None]) -> None:
        """Call `callback` every `period` s of ROS time, as a rclpy timer would (under sim
        time with the EventsExecutor: from the node's own /clock reader, see ClockTimers)."""
        if self._clock_timers is not None:
            self._clock_timers.add(period, callback)
        else:
            self.create_timer(period, callback)

    def ros_now_s(self) -> float:
        """ROS time in seconds (sim time when use_sim_time is set): under the EventsExecutor
        the latest /clock taken in arrival order (ClockTimers), else the ROS clock."""
        if self._clock_timers is not None and self._clock_timers.now_ns is not None:
            return self._clock_timers.now_ns * 1e-9
        return self.get_clock().now().nanoseconds * 1e-9

    def now_s(self) -> float:
        """The time the core is told (ros_now_s; the executive may age records otherwise)."""
        return self.ros_now_s()

    def _on_record(self, name: str):
        def callback(fields: dict[str, Any]) -> None:
            self.publish(self.core.on_record(name, fields, self.now_s()))
        return callback

    def _on_reject(self, reader: RecordSubscription):
        def callback() -> None:
            handler = getattr(self.core, 'on_reject', None)
            if handler is not None:
                self.publish(handler(reader.schema.name, reader.last_reason, self.now_s()))
        return callback

    def _radio_stop(self, msg: Bool) -> None:
        self.core.on_radio_stop(msg.data, self.now_s())

    def _tick(self) -> None:
        self.publish(self.core.tick(self.now_s()))

    def publish(self, outputs: dict[str, dict[str, Any]] | None) -> None:
        """Publish the records a core returned (and log the warnings it noted)."""
        while self._warnings:
            self.get_logger().warn(self._warnings.pop(0))
        for record, fields in (outputs or {}).items():
            if record == self.fault_record:
                self._faulty(record, fields)
            else:
                self.writers[record].publish(fields)

    def _faulty(self, record: str, fields: dict[str, Any]) -> None:
        raw = self.writers[record].pack(fields)
        if self._fault_rng.random() < self.fault_loss:
            return  # lost on the way
        if self.fault_delay:
            self._held.append((self.now_s() + self.fault_delay, raw))
        else:
            self.writers[record].publish_raw(raw)

    def _release(self) -> None:
        now = self.now_s()
        while self._held and self._held[0][0] <= now:
            self.writers[self.fault_record].publish_raw(self._held.pop(0)[1])


def declare_executor(params: Parameters) -> str:
    """The `executor` parameter every node process has (see make_executor)."""
    return params.choice('executor', 'events', "rclpy executor of this node's process: events "
                         "(rclpy's EventsExecutor: about half the CPU, inputs taken in arrival "
                         'order) or single (SingleThreadedExecutor)', ('events', 'single'))


class ClockTimers:
    """A node's sim time and periodic callbacks under the EventsExecutor, from its own FIFO
    /clock reader.

    The EventsExecutor takes every input in the order it arrived. The ROS clock's own /clock
    reader keeps only the newest sample, so in a process that has fallen behind it runs ahead
    of the records still queued, and a record taken late looks late (a false "sensor lost" in
    one full-programme run at 2.4x real time). Read FIFO, /clock is one more input in the
    queue: each record is handled at the sim time it arrived, and a starved node blames
    nobody. The callbacks follow rclpy timer semantics under sim time: due every `period` s,
    at most once per /clock message, periods a jump passed over are skipped.
    """

    def __init__(self, node: Node) -> None:
        self.now_ns: int | None = None  # the latest /clock taken
        self._timers: list[list[Any]] = []  # [period, next due (ns) or None, callback]
        # One /clock reader per node, not two: rclpy's TimeSource keeps a reader of its own,
        # and taking every sample twice cost an idle node 3.9 % of a core against 2.7 % at
        # 113 Hz (bench/rclpy_bench.py). Its reader goes, and this one sets the node's ROS
        # clock (so get_clock() is the same FIFO time). rclpy has no public hook for it:
        # without the attributes, both stay.
        self._time_source = getattr(node, '_time_source', None)
        own = getattr(self._time_source, '_clock_sub', None)
        if own is not None:
            node.destroy_subscription(own)
            self._time_source._clock_sub = None
        # Taken serialized: at 116 Hz in every node, rclpy's conversion to a Clock message cost
        # more than the take itself (bench/rclpy_bench.py: 335 -> 237 us a message at 340 Hz).
        self._msg = Clock()  # one message, re-filled for the TimeSource
        node.create_subscription(Clock, '/clock', self._on_clock, qos.CLOCK_READER, raw=True)

    def add(self, period: float, callback: Callable[[], None]) -> None:
        """One more periodic callback."""
        self._timers.append([round(period * 1e9), None, callback])

    def _on_clock(self, raw: bytes) -> None:
        now = clock_time_ns(raw)
        if now <= 0:
            return  # the world's clock has not started
        self.now_ns = now
        if self._time_source is not None:
            self._msg.clock.sec, self._msg.clock.nanosec = divmod(now, 1_000_000_000)
            self._time_source.clock_callback(self._msg)
        for timer in self._timers:
            period, due, callback = timer
            if due is None or now < due - 10 * period:  # first tick, or sim time went back
                timer[1] = now + period
                continue
            if now >= due:
                skipped = (now - due) // period
                timer[1] = due + (skipped + 1) * period
                callback()


def make_executor(kind: str = 'single') -> Any:
    """The executor for one node process (never MultiThreadedExecutor: anchors.md 3.3).

    `events` is rclpy's EventsExecutor (rclpy.experimental in Jazzy): measured on the demo
    graph it halves each node's CPU (bench/graph_bench.py), which is what lets the full
    programme run faster than real time on two cores. It also takes every input in the order
    it arrived, /clock included, so a record is handled at the sim time it came in even when
    the process falls behind (the SingleThreadedExecutor takes one sample per ready topic per
    turn, and its keep-last-1 clock runs ahead of the records still queued). Two limits of the
    PyPI rclpy 7.1.6 shape the nodes: (msg, info) callbacks raise SystemError (so only a
    SingleThreadedExecutor reader asks for source timestamps) and spin() misses the shutdown
    (spin_main loops on spin_once).
    """
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor()
        except ImportError:  # an rclpy without it
            pass
    return SingleThreadedExecutor()


class _StopRequest:
    """SIGINT / SIGTERM as a request the spin loop takes between callbacks.

    rclpy's own handlers shut the context down from a signal thread at once and raise
    KeyboardInterrupt wherever the main thread is: a callback that is publishing then fails
    with 'context is invalid' and the EventsExecutor logs it FATAL. Under sim time the nodes
    sit idle once the world has stopped, but on the wall clock (the hardware configuration)
    their timers and inputs keep running and every Ctrl-C printed those errors. So the node
    processes install these handlers instead (rclpy.init without its own) and the loop ends
    after the callback in hand; a second signal raises KeyboardInterrupt for a node stuck in
    one.
    """

    def __init__(self) -> None:
        self.requested = False

    def install(self) -> None:
        """Take over SIGINT and SIGTERM (main thread only)."""
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, self._handle)

    def _handle(self, signum: int, _frame: object) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True


_stop = _StopRequest()


def running() -> bool:
    """True while the node process should keep spinning: the context is up and no SIGINT or
    SIGTERM has come (spin_main's handlers)."""
    return not _stop.requested and rclpy.ok()


def _shutting_down(wait: float = 0.5) -> bool:
    """True when SIGINT is shutting the context down (rclpy's signal thread does it a moment
    after the signal). Meanwhile rclpy 7.1 can raise from inside the executor - RCLError
    'context is not valid' between two waits, RuntimeError from take_message - instead of
    ExternalShutdownException; both are a clean exit, any other error is not."""
    deadline = time.monotonic() + wait
    while rclpy.ok():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


TEARDOWN_LIMIT = 2.0  # s: a node's DDS teardown normally takes well under 0.5 s


def _teardown(node: Node | None, spinner: Any, code: int, limit: float = TEARDOWN_LIMIT) -> None:
    """Let go of the node: its own last words (`finish()`: the recorder closes its bag), then
    the executor, the node's entities and the context, the last three bounded by `limit`.

    The executor goes first: destroying entities while the EventsExecutor still took their DDS
    callbacks hung 2 of 6 wall-clock shutdowns. Even so about one in twenty wall-clock
    shutdowns (test_wall_clock_dds, 2 in 44 runs) left a node in Fast DDS's entity deletion
    (seen in `delete_datareader`, py-spy), deaf to SIGINT and SIGTERM until the launcher's
    SIGKILL: a Fast DDS teardown deadlock (eProsima/Fast-DDS#6193 reports a similar one).
    Everything the node owes is done by then, so past `limit` it says so, with every thread's
    stack, and exits with its status rather than wait for a SIGKILL.
    """
    if node is not None and hasattr(node, 'finish'):
        node.finish()
    done = threading.Event()

    def give_up() -> None:
        if done.wait(limit):
            return
        name = node.get_name() if node is not None else 'node'
        print(f'{name}: DDS teardown still blocked after {limit:g} s; exiting without it '
              f'(status {code}). Stacks:', file=sys.stderr, flush=True)
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        sys.stdout.flush()
        os._exit(code)
    threading.Thread(target=give_up, name='teardown_limit', daemon=True).start()
    try:
        if spinner is not None:
            spinner.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    finally:
        done.set()


def spin_main(make_node: Callable[[], Node], args: list[str] | None = None,
              executor: Callable[[], Any] | None = None,
              run: Callable[[Any, Any], int] | None = None) -> int:
    """The rclpy main() idiom for one node: init, spin, clean shutdown, exit status.

    A ParameterError (bad value or parameter file) ends start-up with its one-line message
    and exit status 2; SIGINT and SIGTERM end the spin cleanly, between two callbacks
    (_StopRequest), and the teardown is bounded (_teardown). `run(node, executor)` replaces
    the plain spin for a node with a loop of its own (the world), which checks running().
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    _stop.install()
    node = spinner = None
    code = 0
    try:
        node = make_node()
        spinner = executor() if executor is not None else \
            make_executor(getattr(node, 'executor_kind', 'single'))
        spinner.add_node(node)
        # Start-up objects (rclpy, the codec, the node: ~34,000) out of the collector's reach.
        # A full collection over them took 14 ms (measured, navigation), a pause that lands on
        # whatever record is in flight: the worst sensor-to-traction times were of that size.
        # Frozen, a full collection scans only what the run itself keeps (~0 ms).
        gc.collect()
        gc.freeze()
        if run is not None:
            code = run(node, spinner)
        else:
            while running():  # not spin(): the EventsExecutor's misses the shutdown
                spinner.spin_once(timeout_sec=0.1)
    except ParameterError as exc:
        print(exc, file=sys.stderr)
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:  # noqa: BLE001
        if not _shutting_down():
            code = 1
            raise
    finally:
        _teardown(node, spinner, code)
    return code
