"""The running graph: one process per node, started, watched and stopped in order.

Each node runs the venv's python through `agv_nodes.graph.child` (so it dies with its launcher)
with `--ros-args -r __ns:=<namespace> --params-file <file> --params-file <overrides>`, the second
file holding what the launch sets on top (agv_nodes.graph.parameters, and `-p NODE:NAME:=VALUE`). A
file, not `-p`: whether a plain `-p` beats the file's node-specific entry (`/**/executive:`)
depends on where it stands on the command line, a later file's entry always does, and a file is how
`ros2 launch` passes dict parameters too (test_launch_file.py checks it with rcl's parser). Output
is prefixed with the node's name; shutdown goes in order (the VDA 5050 bridge first, so its master
control hears the truck go OFFLINE while all of it still runs; the world, so time stops; recorder
last, so the bag sees the end); a node that dies ends the launch with a non-zero status (or is
restarted, --respawn). Discovery is localhost-only, on a ROS domain of the graph's own (never 0).

With --vda5050 and no broker named (--mqtt-url, AGV_MQTT_URL) the launcher runs a broker of its
own: mosquitto through the child wrapper, else (not installed) amqtt in a thread of its own
process. Either ends with the launcher however that ends (a SIGKILL too, with no clean-up to
forget), and a clean stop shuts it after the nodes, so the bridge's OFFLINE reaches the master
control first.
"""

import atexit
from dataclasses import replace
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import TYPE_CHECKING, TextIO

from agv_nodes.discovery import use_localhost_discovery
from agv_nodes.graph.claim import claim_domain, claim_graph
from agv_nodes.graph.model import GraphError, NodeSpec, load_graph
from agv_nodes.graph.parameters import (
    Options,
    check_fleet,
    check_realtime,
    check_vda5050,
    floor_parameters,
    launch_units,
    launched,
    override_parameters,
    parameter_file_text,
    realtime_priority,
    silent_records,
    truck_graph,
)

if TYPE_CHECKING:  # imported where the broker starts
    from agv_nodes.mqtt.broker import EmbeddedBroker, Mosquitto

CHILD = 'agv_nodes.graph.child'


class ReadyFile:
    """The world's `ready_file` as a threading.Event: set once seen (even after it is removed)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._seen = False

    def is_set(self) -> bool:
        """Return True once the world has written the file."""
        if not self._seen:
            self._seen = self.path.exists()
        return self._seen

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the world moves (or `timeout` seconds); True if it does."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self.is_set():
            if deadline is not None and time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        return True


class Launch:
    """A running graph."""

    def __init__(self, options: Options) -> None:
        self.o = options
        self.graph = truck_graph(load_graph(options.graph), options)
        self.silent_records = silent_records(self.graph, options)
        check_realtime(options)
        check_vda5050(self.graph, options)
        check_fleet(self.graph, options)
        self.mqtt_url = self._named_broker() if options.vda5050 else None
        self.params = Path(options.params) if options.params else self.graph.parameters
        if not self.params.is_file():
            raise GraphError(f'parameter file {self.params} not found')
        self.domain, self._lock = claim_domain(options.domain_id)
        self._graph_lock: TextIO | None = None
        self.claimed = False
        self.env = dict(os.environ, ROS_DOMAIN_ID=str(self.domain), PYTHONUNBUFFERED='1')
        use_localhost_discovery(self.env)
        self.procs: dict[str, subprocess.Popen] = {}  # by label (units())
        self.exits: dict[str, int | None] = {}  # None: still running when given up on
        self.stopping = False
        self.failed: list[str] = []
        self.escalated: dict[str, str] = {}  # node -> the signal it took to stop (not SIGINT)
        self.lines: list[str] = []
        self._threads: list[threading.Thread] = []
        self._logs: dict[str, TextIO] = {}
        self._overrides = Path(tempfile.mkdtemp(prefix='agv_launch_'))
        self.ready_file = self._overrides / 'world.ready'
        self.moving = ReadyFile(self.ready_file)
        self._units = {label: (spec, ns) for label, spec, ns in self.units()}
        # the MQTT broker the launcher runs, if it runs one
        self.broker: Mosquitto | EmbeddedBroker | None = None
        if options.vda5050:
            self._start_broker()

    def _named_broker(self) -> str | None:
        """Return the broker --mqtt-url or AGV_MQTT_URL names (checked), else None."""
        from agv_nodes.mqtt.broker import broker_url  # amqtt: only with --vda5050

        try:
            return broker_url(self.o.mqtt_url)
        except ValueError as exc:
            raise GraphError(str(exc)) from None

    def _start_broker(self) -> None:
        """Start the embedded broker unless one is named; the bridge's URL goes into self.o.

        Started here, not in start(), so that its URL is a start-up fact the launcher prints
        with the others; last, so that no check can fail with a broker left running.
        """
        from agv_nodes.mqtt.broker import local_broker  # mosquitto, else the embedded amqtt

        if self.mqtt_url is None:
            self.broker = local_broker()
            try:
                self.mqtt_url = self.broker.start()
            except RuntimeError as exc:
                shutil.rmtree(self._overrides, ignore_errors=True)
                if self._lock is not None:
                    self._lock.close()
                raise GraphError(str(exc)) from None
        self.o = replace(self.o, mqtt_url=self.mqtt_url)  # a copy: the caller's stays as given

    def specs(self) -> list[NodeSpec]:
        """Nodes to start, in order (of one truck: a fleet starts the truck nodes per truck)."""
        return [n for n in self.graph.nodes if launched(n, self.o)]

    def join(self) -> None:
        """Give this process the graph's domain and discovery (before its first participant)."""
        os.environ['ROS_DOMAIN_ID'] = str(self.domain)
        use_localhost_discovery()

    def units(self) -> list[tuple[str, NodeSpec, str]]:
        """Return the processes to start, in order: (label, node, namespace) (launch_units)."""
        return launch_units(self.graph, self.o)

    def command(self, spec: NodeSpec, namespace: str | None = None,
                label: str | None = None) -> list[str]:
        """Return the command line of one node (`namespace`: one truck's of a fleet)."""
        exe = Path(sys.executable).parent / spec.executable
        cmd = [str(exe)] if exe.exists() else [sys.executable, '-m', spec.module]
        cmd += ['--ros-args', '-r', f'__node:={spec.name}']
        namespace = self.o.namespace if namespace is None else namespace
        if namespace:
            cmd += ['-r', f'__ns:={namespace}']
        overrides = self._overrides / f'{(label or spec.name).replace("/", "_")}.yaml'
        options = replace(self.o, namespace=namespace)
        if self.o.trucks and spec.role == 'world':
            content = floor_parameters(self.graph, spec, options, self.ready_file)
        else:
            content = {f'/**/{spec.name}': {'ros__parameters': (
                override_parameters(self.graph, spec, options, self.ready_file))}}
        overrides.write_text(parameter_file_text(content))
        return cmd + ['--params-file', str(self.params), '--params-file', str(overrides)]

    def _pump(self, name: str, stream) -> None:
        width = max(len(label) for label in self._units)
        log = self._logs.get(name)
        for raw in stream:
            line = raw.rstrip('\n')
            if log is not None:
                log.write(line + '\n')
            self.lines.append(f'{name}: {line}')
            if not self.o.quiet:
                print(f'[{name:{width}s}] {line}', flush=True)

    def child_command(self, spec: NodeSpec, namespace: str | None = None,
                      label: str | None = None) -> list[str]:
        """Return command() through the child wrapper (SIGTERM if the launcher dies; priority)."""
        command = [sys.executable, '-m', CHILD, str(os.getpid())]
        if priority := realtime_priority(spec, self.o):
            command += ['--sched-fifo', str(priority)]
        return command + self.command(spec, namespace, label)

    def _start(self, label: str) -> None:
        spec, namespace = self._units[label]
        proc = subprocess.Popen(self.child_command(spec, namespace, label), env=self.env,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                bufsize=1, start_new_session=True)
        self.procs[label] = proc
        thread = threading.Thread(target=self._pump, args=(label, proc.stdout), daemon=True)
        thread.start()
        self._threads.append(thread)

    def claim(self) -> None:
        """Claim this graph's domain and namespace (agv_nodes.graph.claim); once.

        GraphError in one line when a graph already runs there. A domain chosen free is
        claimed already (no other participant is on it).
        """
        if self.claimed:
            return
        if self._lock is None:
            units = {('/' + ns.strip('/'), spec.name) for spec, ns in self._units.values()}
            self._graph_lock = claim_graph(self.domain, self.o.namespace, units)
        self.claimed = True

    def start(self) -> None:
        """Start every node (recorder first, world last), once claim() has found no graph."""
        self.claim()
        if self.o.log_dir:
            self.o.log_dir.mkdir(parents=True, exist_ok=True)
            # Line-buffered: a log is readable while its node runs, not only after it ends.
            self._logs = {label: open(  # noqa: SIM115
                self.o.log_dir / f'{label.replace("/", "_")}.log', 'w', buffering=1)
                for label, _s, _n in self.units()}
        atexit.register(self._stop_at_exit)  # never leave a graph behind on the domain
        for label in self._units:
            self._start(label)

    def _stop_at_exit(self) -> None:
        if not self.stopping:
            self.stop(timeout=2.0)

    def cpu_seconds(self) -> dict[str, float]:
        """Return each process's CPU time so far (user + system, all its threads), s.

        The child wrapper execs the node, so a process's pid is its node's; one whose /proc
        entry is gone (reaped, or not Linux) is left out.
        """
        out: dict[str, float] = {}
        for label, proc in self.procs.items():
            try:
                stat = Path(f'/proc/{proc.pid}/stat').read_text()
            except OSError:
                continue
            fields = stat.rsplit(')', 1)[1].split()
            out[label] = (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')
        return out

    def poll(self) -> list[str]:
        """Check the processes; return the names of those that died unexpectedly."""
        dead = []
        for name, proc in list(self.procs.items()):
            code = proc.poll()
            if code is None or name in self.exits:
                continue
            self.exits[name] = code
            if self.stopping:
                continue
            spec = self._units[name][0]
            if spec.role == 'world' and code == 0:
                continue  # the world ran its `duration`
            dead.append(name)
            message = f'agv-launch: node {name} exited with status {code}'
            if self.o.respawn and spec.role == 'node':
                print(f'{message}; respawning', file=sys.stderr, flush=True)
                self.respawn(name)
            else:
                print(message, file=sys.stderr, flush=True)
                self.failed.append(name)
        return dead

    def respawn(self, label: str) -> None:
        """Start a node that died again (after a second, so that its peers see it go)."""
        self.exits.pop(label, None)
        time.sleep(1.0)
        self._start(label)

    def world_done(self) -> bool:
        """Return True once the world process has exited."""
        proc = self.procs.get('world')
        return proc is not None and proc.poll() is not None

    def stop(self, timeout: float = 5.0) -> None:
        """Shut the graph down in order: viewer, master, bridge, world, nodes, recorder.

        Then the embedded MQTT broker, if the launcher runs one.
        """
        self.stopping = True
        self.moving.is_set()  # note a world that moved before its file goes with the directory
        for group in ('viewer', 'master', 'bridge', 'world', 'node', 'recorder'):
            names = [n for n in self.procs if self._units[n][0].role == group]
            for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 3.0),
                              (signal.SIGKILL, 3.0)):
                if not (alive := [n for n in names if self.procs[n].poll() is None]):
                    break
                if sig != signal.SIGINT:
                    print(f'agv-launch: {", ".join(alive)} still running: sending '
                          f'{signal.Signals(sig).name}', file=sys.stderr, flush=True)
                    self.escalated.update(dict.fromkeys(alive, signal.Signals(sig).name))
                for name in alive:
                    self.procs[name].send_signal(sig)
                deadline = time.monotonic() + wait
                for name in alive:
                    try:
                        self.procs[name].wait(timeout=max(0.05, deadline - time.monotonic()))
                    except subprocess.TimeoutExpired:
                        pass
            for name in names:
                self.exits.setdefault(name, self.procs[name].poll())
        if self.broker is not None:
            try:
                self.broker.stop()
            except RuntimeError as exc:  # its daemon thread still ends with this process
                print(f'agv-launch: {exc}', file=sys.stderr, flush=True)
        for thread in self._threads:
            thread.join(timeout=2.0)
        for log in self._logs.values():
            log.close()
        shutil.rmtree(self._overrides, ignore_errors=True)
        if self._graph_lock is not None:  # the namespace is free again
            self._graph_lock.close()
            self._graph_lock = None

    def run(self, duration: float | None = None) -> int:
        """Start, wait for a signal, a dead node or the world's end, stop; exit status."""
        stop = threading.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda *_: stop.set())
        self.start()
        t0 = time.monotonic()
        code = 0
        while not stop.is_set():
            if self.poll() and not self.o.respawn:
                code = 1
                break
            if self.world_done():
                code = self.exits.get('world') or 0  # done: its code is in
                break
            if duration and time.monotonic() - t0 > duration:
                break
            stop.wait(0.2)
        self.stop()
        if self.failed:
            print(f'agv-launch: failed nodes: {", ".join(self.failed)}', file=sys.stderr)
            code = code or 1
        return code
