"""CoreNode: the thin rclpy wrapper every sub-processor node is made of.

It creates one RecordPublisher per record the core writes and one RecordSubscription per record
it reads, both from the schemas' writer/readers (the same port declarations the lock-step
harness uses), feeds accepted records and rejections to the core, runs the core's timer on the
ROS clock (sim time under use_sim_time), subscribes hw/radio_stop for cores that want it, and
publishes whatever the core returns.
"""

from __future__ import annotations

from collections.abc import Callable
import os
import random
import sys
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Bool

from agv_nodes import qos
from agv_nodes.params import ParameterError, Parameters
from agv_nodes.records import codec
from agv_nodes.ros_ports import InputDiagnostics, RecordPublisher, RecordSubscription


class CoreNode(Node):
    """A node around one core; subclasses declare parameters and build the core."""

    def attach(self, core: Any, params: Parameters) -> None:
        """Declare record_integrity, then create the core's ports and timer."""
        integrity = params.choice('record_integrity', 'e2e', 'end-to-end protection of the '
                                  'inter-processor records (none: a legacy peer sending plain '
                                  'thesis records)', ('e2e', 'none'))
        self.core = core
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
                                                   callback=self._on_record(s.name))
                        for s in reads}
        for reader in self.readers.values():
            reader.on_reject = self._on_reject(reader)
        if hasattr(core, 'on_radio_stop'):
            self.create_subscription(Bool, 'hw/radio_stop', self._radio_stop,
                                     qos.RECORD_READER)
        if core.period:
            self.timer = self.create_timer(core.period, self._tick)
        if self.fault_record and self.fault_delay:
            self.create_timer(0.001, self._release)  # fires once per /clock step
        self.input_diagnostics = InputDiagnostics(self, self.readers,
                                                  health=getattr(core, 'health', None))

    def now_s(self) -> float:
        """ROS time in seconds (sim time when use_sim_time is set)."""
        return self.get_clock().now().nanoseconds * 1e-9

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
        """Publish the records a core returned."""
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


def make_executor() -> Any:
    """The executor for one node process (never MultiThreadedExecutor: anchors.md 3.3).

    The SingleThreadedExecutor is the default. AGV_EXECUTOR=events tries rclpy's experimental
    EventsExecutor (a third of the CPU in anchors.md 3.2), but with the PyPI rclpy 7.1.6 and
    sim time it spun at ~22 % CPU per process without ever running the graph here, so it stays
    an experiment.
    """
    if os.environ.get('AGV_EXECUTOR', 'single') == 'events':
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor()
        except ImportError:  # an rclpy without it
            pass
    return SingleThreadedExecutor()


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


def spin_main(make_node: Callable[[], Node], args: list[str] | None = None,
              executor: Callable[[], Any] | None = None,
              run: Callable[[Any, Any], int] | None = None) -> int:
    """The rclpy main() idiom for one node: init, spin, clean shutdown, exit status.

    A ParameterError (bad value or parameter file) ends start-up with its one-line message
    and exit status 2; SIGINT and SIGTERM end the spin cleanly. `run(node, executor)` replaces
    the plain spin for a node with a loop of its own (the world).
    """
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        node = make_node()
        spinner = executor() if executor is not None else make_executor()
        spinner.add_node(node)
        if run is not None:
            code = run(node, spinner)
        else:
            spinner.spin()
    except ParameterError as exc:
        print(exc, file=sys.stderr)
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:  # noqa: BLE001
        if not _shutting_down():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
