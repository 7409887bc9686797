"""The life of one node process: rclpy's main() idiom, clean stops, a bounded teardown.

Every console script's main() calls `spin_main`. Every node process dies with the process that
started it (`die_with_parent`).
"""

from collections.abc import Callable
import ctypes
import faulthandler
import gc
import os
import signal
import sys
import threading
import time
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from agv_nodes import PARENT_AT_START
from agv_nodes.params import ParameterError, params_files
from agv_nodes.settings import ParameterFileError, read_parameter_file


def make_executor(kind: str = 'single') -> Any:
    """Return the executor for one node process (docs/architecture.md, "Time and pacing").

    Never MultiThreadedExecutor: it drops messages at these rates. `events` is rclpy's
    EventsExecutor (rclpy.experimental in Jazzy): it halves each node's CPU (bench/graph_bench.py),
    which lets the full programme outrun real time on two cores, and takes every input in arrival
    order, /clock included (the SingleThreadedExecutor takes one sample per ready topic per turn,
    its keep-last-1 clock running ahead of the records queued). Limits of the PyPI rclpy 7.1.6:
    (msg, info) callbacks raise SystemError (so only a SingleThreadedExecutor reader asks for
    source timestamps) and spin() misses the shutdown (spin_main loops on spin_once).
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

    rclpy's own handlers shut the context down at once from a signal thread and raise
    KeyboardInterrupt wherever the main thread is: a publishing callback then fails with 'context
    is invalid', logged FATAL by the EventsExecutor, on each wall-clock Ctrl-C (timers and inputs
    keep running). A second signal raises KeyboardInterrupt for a node stuck in a callback.
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
        # a node asked to stop is gone within STOP_LIMIT whatever holds it: faulthandler's
        # watchdog is a C thread, so it fires even while a blocked call holds the GIL (as rclpy
        # does in Fast DDS's entity deletion, where the teardown_limit thread cannot run)
        faulthandler.dump_traceback_later(STOP_LIMIT, exit=True)


_stop = _StopRequest()


def running() -> bool:
    """Return True while the context is up and no SIGINT or SIGTERM has come."""
    return not _stop.requested and rclpy.ok()


def _shutting_down(wait: float = 0.5) -> bool:
    """Return True when SIGINT shuts the context down (rclpy 7.1 may raise meanwhile: clean)."""
    deadline = time.monotonic() + wait
    while rclpy.ok():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


TEARDOWN_LIMIT = 2.0  # s: a node's DDS teardown normally takes well under 0.5 s
STOP_LIMIT = 15.0  # s from SIGINT/SIGTERM to exit, teardown included, before the watchdog's exit


def _teardown(node: Node | None, spinner: Any, code: int, limit: float = TEARDOWN_LIMIT) -> None:
    """Let go of the node: `finish()`, then executor, entities and context, bounded by `limit`.

    The executor goes first: destroying entities while the EventsExecutor still takes their DDS
    callbacks can hang. Even so a wall-clock shutdown can deadlock in Fast DDS's entity deletion
    (`delete_datareader`, py-spy), deaf to SIGINT and SIGTERM; everything the node owes is done by
    then, so past `limit` it says so, with every thread's stack, and exits with its status rather
    than wait for the launcher's SIGKILL.
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


PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Have Linux send this process SIGTERM when its parent exits (prctl PR_SET_PDEATHSIG).

    A node orphaned by a SIGKILLed launcher would run on, cross-talking with the next graph on
    its domain and holding the truck's last outputs. SIGTERM ends the spin cleanly. The parent
    here is whatever started the node: agv-launch's child wrapper (which asks the same for
    itself), ros2 launch, ros2 run or a shell; under systemd it is PID 1, which never exits.
    """
    if not sys.platform.startswith('linux'):
        return
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    # the parent as it was before the imports: one that died before the request was in place
    # has left this process to a new parent
    if os.getppid() != PARENT_AT_START:
        os.kill(os.getpid(), signal.SIGTERM)


def spin_main(make_node: Callable[[], Node], args: list[str] | None = None,
              executor: Callable[[], Any] | None = None,
              run: Callable[[Any, Any], int] | None = None) -> int:
    """Run the rclpy main() idiom for one node: init, spin, clean shutdown, exit status.

    `run(node, executor)` replaces the spin for a node with a loop of its own (the world).
    """
    die_with_parent()
    try:  # before rclpy reads them: its own error names neither the file nor the line
        for path in params_files(sys.argv if args is None else args):
            read_parameter_file(path)
    except ParameterFileError as exc:
        print(exc, file=sys.stderr)
        return 2
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    _stop.install()
    node = spinner = None
    code = 0
    try:
        node = make_node()
        spinner = executor() if executor is not None else \
            make_executor(getattr(node, 'executor_kind', 'single'))
        spinner.add_node(node)
        # Start-up objects (~34,000) out of the collector's reach: a full collection over them
        # took 14 ms, the size of the worst sensor-to-traction times; frozen, ~0 ms.
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
