"""agv-launch: start the graph one process per node, as `ros2 launch` would on a ROS install.

It reads the graph description (config/graph.yaml) and the parameter file, and starts every
node as its own process with the venv's python: `--ros-args -r __ns:=<namespace>
--params-file <file> --params-file <overrides>`, where the second file holds what the launch
sets on top (use_sim_time, record_integrity, the world's wait lists, `-p NODE:NAME:=VALUE`).
A second file, not `-p`: with rclpy 7.1 a node-specific entry of the parameter file
(`/**/executive:`) beats a plain `-p name:=value`, so `-p` could not override the file; a later
file's entry for the same node does, which is also how `ros2 launch` passes dict parameters
(measured: test_launch_file.py). Output is prefixed with
the node's name; SIGINT/SIGTERM are forwarded and the graph is shut down in order (world first,
so time stops, recorder last, so the bag sees the end); a node that dies is reported with its
exit status and ends the launch with a non-zero status (or is restarted with --respawn).
Discovery is localhost-only; the domain id is settable (never 0: the launcher refuses it).

The world waits before it moves until every record topic of the graph has its writer and its
readers (and the recorder, when recording): the graph is complete before time starts.
"""

from __future__ import annotations

import argparse
import atexit
from dataclasses import dataclass, field
import fcntl
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import TextIO

import yaml

from agv_nodes.package_share import config_dir
from agv_nodes.records import codec

ROLES = ('node', 'world', 'recorder')


class GraphError(ValueError):
    """A graph description that cannot be used (names the file, key and value)."""


@dataclass
class NodeSpec:
    """One node of the graph."""

    name: str
    executable: str
    module: str
    role: str = 'node'
    realtime: bool = False  # on the sensor-to-traction chain: SCHED_FIFO with --realtime


@dataclass
class Graph:
    """The graph description."""

    name: str
    nodes: list[NodeSpec]
    parameters: Path
    file: Path

    def node(self, name: str) -> NodeSpec:
        """The node called `name`."""
        return next(n for n in self.nodes if n.name == name)


def load_graph(file: Path | None = None) -> Graph:
    """Load and check config/graph.yaml (or another description)."""
    file = Path(file) if file else config_dir() / 'graph.yaml'
    try:
        doc = yaml.safe_load(file.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise GraphError(f'{file}: cannot read: {" ".join(str(exc).split())}') from None
    if not isinstance(doc, dict) or not isinstance(doc.get('nodes'), list):
        raise GraphError(f'{file}: key nodes: a list of nodes is required')
    nodes = []
    for i, spec in enumerate(doc['nodes']):
        if not isinstance(spec, dict):
            raise GraphError(f'{file}: key nodes[{i}]: {spec!r} must be a mapping')
        for key in ('name', 'executable', 'module'):
            if not isinstance(spec.get(key), str) or not spec[key]:
                raise GraphError(f'{file}: key nodes[{i}].{key}: {spec.get(key)!r} missing')
        role = spec.get('role', 'node')
        if role not in ROLES:
            raise GraphError(f'{file}: key nodes[{i}].role: {role!r} not one of {ROLES}')
        realtime = spec.get('realtime', False)
        if not isinstance(realtime, bool):
            raise GraphError(f'{file}: key nodes[{i}].realtime: {realtime!r} is not true/false')
        nodes.append(NodeSpec(spec['name'], spec['executable'], spec['module'], role,
                              realtime))
    params = file.parent / str(doc.get('parameters', 'agv_demo.yaml'))
    return Graph(str(doc.get('graph', 'agv')), nodes, params, file)


def wait_lists(graph: Graph, world: bool, recording: bool) -> tuple[list[str], list[str]]:
    """Topics that need readers / writers before the world moves (relative names).

    Each topic needs *all* its readers ('topic:N'): the graph's readers from the schemas, the
    world's pacing subscription on records it does not read itself, and the recorder. Counting
    only one let the world's own pacing reader satisfy the wait while traction had not yet
    matched the executive, so traction missed the 00H that arms it (a start-up trip).
    """
    subs, pubs = [], []
    for name, n in record_readers(graph, world, recording).items():
        s = codec()[name]
        pubs.append(s.topic)
        subs.append(f'{s.topic}:{n}' if n > 1 else s.topic)
    return sorted(set(subs)), sorted(set(pubs))


def record_readers(graph: Graph, world: bool, recording: bool) -> dict[str, int]:
    """Each record whose writer and at least one reader run -> its number of readers (the
    graph's, the world's pacing reader of a record it does not read itself, the recorder)."""
    running = {n.name for n in graph.nodes if n.role == 'node' or (n.role == 'world' and world)}
    paced = set(paced_records(graph)) if world else set()
    out = {}
    for s in codec():
        if s.kind == 'ground_truth':
            continue
        readers_up = [r for r in s.readers if r in running]
        if s.writer in running and readers_up:
            pacing = s.name in paced and 'world' not in s.readers
            out[s.name] = len(readers_up) + pacing + recording
    return out


def wait_links(graph: Graph, recording: bool = False) -> list[str]:
    """The world's `wait_for_links`: both ends of every record link of the graph.

    'reader:record' - the reader's node has matched the record's writer - for each reader of
    each record (both ends launched), the world's pacing readers included; and
    'writer>record:N' - the writer has matched all N readers (record_readers). Discovery is
    two-sided and either side may lag: a writer that has not matched a reader sends it nothing
    (a volatile reader never sees what went before), and a reader that has not matched the
    writer drops what comes. Counting readers from the world's side (wait_lists) said neither.
    With the reader ends only, a CI run's navigation still had no sensor status when its
    first task came (0.7 s of sim time) and called the sensor lost, as one fresh-clone
    rehearsal had before; an unmatched writer's end is the one gap left that explains both
    (not caught in the act).
    """
    running = {n.name for n in graph.nodes if n.role in ('node', 'world')}
    links = set()
    for s in codec():
        if s.kind == 'ground_truth' or s.writer not in running:
            continue
        links.update(f'{r}:{s.name}' for r in s.readers if r in running)
    if 'world' in running:
        links.update(f'world:{name}' for name in paced_records(graph))
    for name, n in record_readers(graph, 'world' in running, recording).items():
        links.add(f'{codec()[name].writer}>{name}:{n}')
    return sorted(links)


def paced_records(graph: Graph) -> list[str]:
    """Every record a node of the graph writes: the world waits for the slowest (pacing.py)."""
    running = {n.name for n in graph.nodes if n.role == 'node'}
    return sorted(s.name for s in codec() if s.writer in running)


def pace_slack(faults: dict[str, dict[str, float]]) -> list[str]:
    """World `pace_slack` entries for injected faults: the world must not wait for a record
    that is late by design (delay, plus a /clock step of release) or lost (three periods: a
    run of four losses at 10 % is 1 in 10,000)."""
    out = []
    for record, fault in sorted(faults.items()):
        slack = fault.get('delay', 0.0) + (0.01 if fault.get('delay') else 0.0)
        if fault.get('loss'):
            slack += 3 * codec()[record].period_ms / 1000.0
        out.append(f'{record}:{slack:g}')
    return out


def parse_fault(text: str, graph: Graph) -> tuple[str, dict[str, float]]:
    """'RECORD:loss=0.1,delay=0.02' -> (record, {'loss': 0.1, 'delay': 0.02})."""
    record, _, spec = text.partition(':')
    c = codec()
    writers = {n.name for n in graph.nodes if n.role == 'node'}
    if record not in c or c[record].writer not in writers:
        raise GraphError(f'--fault {text!r}: {record!r} is not a record a node of the graph '
                         f'writes ({", ".join(s.name for s in c if s.writer in writers)})')
    out: dict[str, float] = {}
    for item in filter(None, spec.split(',')):
        key, _, value = item.partition('=')
        try:
            number = float(value)
        except ValueError:
            number = -1.0
        if key not in ('loss', 'delay', 'seed') or number < 0 or (key == 'loss' and number > 1):
            raise GraphError(f'--fault {text!r}: {item!r} (expected loss=0..1, delay=S, seed=N)')
        out[key] = number
    if not out:
        raise GraphError(f'--fault {text!r}: nothing to inject (loss=..., delay=...)')
    return record, out


def node_parameters(graph: Graph, spec: NodeSpec, options: Options) -> dict[str, object]:
    """The parameters the launch sets for one node on top of the parameter file.

    The one source for both agv-launch and launch/agv_demo.launch.py (a test compares them).
    """
    out: dict[str, object] = {'use_sim_time': options.use_sim_time}
    if spec.role == 'node':
        out['record_integrity'] = options.record_integrity
        for record, fault in options.faults.items():
            if codec()[record].writer == spec.name:
                out.update(fault_record=record, fault_loss=fault.get('loss', 0.0),
                           fault_delay=fault.get('delay', 0.0),
                           fault_seed=int(fault.get('seed', 1)))
    if spec.role == 'world':
        subs, pubs = wait_lists(graph, True, options.bag is not None)
        out.update(time_factor=float(options.time_factor), publish_clock=options.use_sim_time,
                   wait_for_subscribers=subs, wait_for_publishers=pubs,
                   wait_for_links=wait_links(graph, options.bag is not None),
                   pace_on=paced_records(graph))
        if options.faults:
            out['pace_slack'] = pace_slack(options.faults)
        if options.layout:
            out['layout'] = options.layout
    if spec.role == 'recorder':
        out['bag'] = str(options.bag)
    return out


def realtime_priority(spec: NodeSpec, options: Options) -> int:
    """The SCHED_FIFO priority one node runs at (0 = the normal scheduler).

    With `--realtime N` (launch file: realtime:=N) the nodes marked `realtime` in the graph
    description - the sensor-to-traction chain and the world that feeds it - run at real-time
    priority N, as a robot's control processes would; each of the 1983 sub-systems had a Z-80
    of its own. The one source for agv-launch and the launch file (a test compares them).
    """
    return options.realtime if spec.realtime else 0


def check_realtime(options: Options) -> None:
    """Refuse a --realtime the graph cannot use, naming why (before anything starts)."""
    if not options.realtime:
        return
    if not 1 <= options.realtime <= 99:
        raise GraphError(f'--realtime {options.realtime}: a SCHED_FIFO priority is 1-99')
    if options.time_factor <= 0:
        raise GraphError(f'--realtime {options.realtime} needs a time factor > 0: at time '
                         'factor 0 the world never sleeps, and at real-time priority it would '
                         'hold a core against every other node')
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:  # try it on this thread, then back: a graph must not start half real-time
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(options.realtime))
        os.sched_setscheduler(0, policy, param)
    except PermissionError:
        raise GraphError(f'--realtime {options.realtime}: this user may not use SCHED_FIFO '
                         '(it needs CAP_SYS_NICE, or an rtprio limit in '
                         '/etc/security/limits.conf)') from None


def override_parameters(graph: Graph, spec: NodeSpec, options: Options) -> dict[str, object]:
    """node_parameters() plus the node's `-p NAME:=VALUE` extras (values parsed as YAML)."""
    out = node_parameters(graph, spec, options)
    for arg in options.extra.get(spec.name, []):
        name, _sep, text = arg.partition(':=')
        try:
            out[name] = yaml.safe_load(text) if text else ''
        except yaml.YAMLError as exc:
            raise GraphError(f'-p {spec.name}:{arg}: value is not YAML ({exc})') from exc
    return out


def claim_domain(explicit: int | None = None) -> tuple[int, TextIO | None]:
    """A ROS domain id for this graph: explicit, ROS_DOMAIN_ID, or a free one by lock file."""
    if explicit is None and os.environ.get('ROS_DOMAIN_ID'):
        explicit = int(os.environ['ROS_DOMAIN_ID'])
    if explicit is not None:
        if not 1 <= explicit <= 232:
            raise GraphError(f'domain id {explicit}: use 1-232 (never 0: other graphs on this '
                             'host may be on it)')
        return explicit, None
    start = 1 + os.getpid() % 200
    for i in range(232):
        domain = 1 + (start + i - 1) % 232
        handle = open(f'/tmp/agv_nodes_ros_domain_{domain}.lock', 'w')  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return domain, handle
        except OSError:
            handle.close()
    raise GraphError('no free ROS domain id 1-232 on this host')


@dataclass
class Options:
    """Everything agv-launch can be told."""

    graph: Path | None = None
    params: Path | None = None
    namespace: str = ''
    use_sim_time: bool = True
    time_factor: float = 1.0
    record_integrity: str = 'e2e'
    world: str = 'sim'
    domain_id: int | None = None
    bag: Path | None = None
    respawn: bool = False
    layout: str | None = None
    extra: dict[str, list[str]] = field(default_factory=dict)  # node -> extra -p args
    # record -> {'loss': fraction, 'delay': s}: injected at its writer (--fault; issue 9)
    faults: dict[str, dict[str, float]] = field(default_factory=dict)
    quiet: bool = False
    log_dir: Path | None = None
    realtime: int = 0  # SCHED_FIFO priority of the graph's `realtime` nodes (0 = off)


class Launch:
    """A running graph."""

    def __init__(self, options: Options) -> None:
        self.o = options
        self.graph = load_graph(options.graph)
        check_realtime(options)
        self.params = Path(options.params) if options.params else self.graph.parameters
        if not self.params.is_file():
            raise GraphError(f'parameter file {self.params} not found')
        self.domain, self._lock = claim_domain(options.domain_id)
        self.env = dict(os.environ, ROS_DOMAIN_ID=str(self.domain),
                        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
        self.env.pop('ROS_LOCALHOST_ONLY', None)
        self.procs: dict[str, subprocess.Popen] = {}
        self.exits: dict[str, int] = {}
        self.moving = threading.Event()
        self.stopping = False
        self.failed: list[str] = []
        self.escalated: dict[str, str] = {}  # node -> the signal it took to stop (not SIGINT)
        self.lines: list[str] = []
        self._threads: list[threading.Thread] = []
        self._logs: dict[str, TextIO] = {}
        self._overrides = Path(tempfile.mkdtemp(prefix='agv_launch_'))

    def specs(self) -> list[NodeSpec]:
        """Nodes to start, in order."""
        out = []
        for n in self.graph.nodes:
            if n.role == 'world' and self.o.world == 'none':
                continue
            if n.role == 'recorder' and self.o.bag is None:
                continue
            out.append(n)
        return out

    def command(self, spec: NodeSpec) -> list[str]:
        """The command line of one node."""
        exe = Path(sys.executable).parent / spec.executable
        cmd = [str(exe)] if exe.exists() else [sys.executable, '-m', spec.module]
        cmd += ['--ros-args', '-r', f'__node:={spec.name}']
        if self.o.namespace:
            cmd += ['-r', f'__ns:={self.o.namespace}']
        overrides = self._overrides / f'{spec.name}.yaml'
        overrides.write_text(yaml.safe_dump({f'/**/{spec.name}': {'ros__parameters': (
            override_parameters(self.graph, spec, self.o))}}))
        return cmd + ['--params-file', str(self.params), '--params-file', str(overrides)]

    def _pump(self, name: str, stream) -> None:
        width = max(len(s.name) for s in self.graph.nodes)
        log = self._logs.get(name)
        for raw in stream:
            line = raw.rstrip('\n')
            if log is not None:
                log.write(line + '\n')
            if 'moving at time_factor' in line:
                self.moving.set()
            self.lines.append(f'{name}: {line}')
            if not self.o.quiet:
                print(f'[{name:{width}s}] {line}', flush=True)

    def child_command(self, spec: NodeSpec) -> list[str]:
        """command() through launch_child: the node gets SIGTERM if this launcher dies (even
        by SIGKILL), and takes its real-time priority (if any) before it execs."""
        command = [sys.executable, '-m', 'agv_nodes.launch_child', str(os.getpid())]
        priority = realtime_priority(spec, self.o)
        if priority:
            command += ['--sched-fifo', str(priority)]
        return command + self.command(spec)

    def _start(self, spec: NodeSpec) -> None:
        command = self.child_command(spec)
        proc = subprocess.Popen(command, env=self.env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, bufsize=1,
                                start_new_session=True)
        self.procs[spec.name] = proc
        thread = threading.Thread(target=self._pump, args=(spec.name, proc.stdout), daemon=True)
        thread.start()
        self._threads.append(thread)

    def start(self) -> None:
        """Start every node (recorder first, world last)."""
        if self.o.log_dir:
            self.o.log_dir.mkdir(parents=True, exist_ok=True)
            self._logs = {s.name: open(self.o.log_dir / f'{s.name}.log', 'w')  # noqa: SIM115
                          for s in self.specs()}
        atexit.register(self._stop_at_exit)  # never leave a graph behind on the domain
        for spec in self.specs():
            self._start(spec)

    def _stop_at_exit(self) -> None:
        if not self.stopping:
            self.stop(timeout=2.0)

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
            spec = self.graph.node(name)
            if spec.role == 'world' and code == 0:
                continue  # the world ran its `duration`
            dead.append(name)
            message = f'agv-launch: node {name} exited with status {code}'
            if self.o.respawn and spec.role == 'node':
                print(f'{message}; respawning', file=sys.stderr, flush=True)
                del self.exits[name]
                time.sleep(1.0)
                self._start(spec)
            else:
                print(message, file=sys.stderr, flush=True)
                self.failed.append(name)
        return dead

    def world_done(self) -> bool:
        """True once the world process has exited."""
        proc = self.procs.get('world')
        return proc is not None and proc.poll() is not None

    def stop(self, timeout: float = 5.0) -> None:
        """Shut the graph down in order: world, nodes, recorder (SIGINT, then SIGTERM, KILL)."""
        self.stopping = True
        for group in ('world', 'node', 'recorder'):
            names = [n for n in self.procs if self.graph.node(n).role == group]
            for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 3.0),
                              (signal.SIGKILL, 3.0)):
                alive = [n for n in names if self.procs[n].poll() is None]
                if not alive:
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
        for thread in self._threads:
            thread.join(timeout=2.0)
        for log in self._logs.values():
            log.close()
        shutil.rmtree(self._overrides, ignore_errors=True)

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
                code = self.exits.get('world', 0)
                break
            if duration and time.monotonic() - t0 > duration:
                break
            stop.wait(0.2)
        self.stop()
        if self.failed:
            print(f'agv-launch: failed nodes: {", ".join(self.failed)}', file=sys.stderr)
            code = code or 1
        return code


def build_parser() -> argparse.ArgumentParser:
    """agv-launch arguments (also used by agv-demo)."""
    ap = argparse.ArgumentParser(prog='agv-launch', description=__doc__.splitlines()[0])
    ap.add_argument('--graph', type=Path, help='graph description (default config/graph.yaml)')
    ap.add_argument('--params', type=Path, help="ROS parameter file (default: the graph's)")
    ap.add_argument('--namespace', default='', help='e.g. /agv2 for a second truck')
    ap.add_argument('--use-sim-time', choices=('true', 'false'), default='true')
    ap.add_argument('--time-factor', type=float, default=1.0,
                    help='simulated seconds per real second (0 = as fast as possible)')
    ap.add_argument('--record-integrity', choices=('e2e', 'none'), default='e2e')
    ap.add_argument('--world', choices=('sim', 'none'), default='sim',
                    help='none: the hardware topics come from drivers')
    ap.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID 1-232 (default: a free one)')
    ap.add_argument('--bag', type=Path, help='record every topic into this new bag directory')
    ap.add_argument('--layout', help='world layout (overrides the parameter file)')
    ap.add_argument('--respawn', action='store_true', help='restart nodes that die')
    ap.add_argument('--duration', type=float, help='stop after this many real seconds')
    ap.add_argument('--log-dir', type=Path, help="also write each node's output here")
    ap.add_argument('--fault', action='append', default=[], metavar='RECORD:loss=P,delay=S',
                    help='lose a fraction of one record and/or delay it (sim s) at its writer, '
                    'e.g. navigation_status:loss=0.1 or traction_link:delay=0.02')
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NODE:NAME:=VALUE',
                    help='extra parameter for one node, e.g. traction:control:=closed_loop')
    ap.add_argument('--realtime', type=int, default=0, metavar='PRIORITY',
                    help='run the sensor-to-traction chain (the `realtime` nodes of the graph) '
                    'at this SCHED_FIFO priority, 1-99; needs a time factor > 0 and the right '
                    'to (root or CAP_SYS_NICE); default 0: the normal scheduler')
    return ap


def options_from(args: argparse.Namespace) -> Options:
    """Options from parsed arguments."""
    extra: dict[str, list[str]] = {}
    for item in args.param:
        node, sep, rest = item.partition(':')
        if not sep or ':=' not in rest:
            raise GraphError(f'-p {item!r}: expected NODE:NAME:=VALUE')
        extra.setdefault(node, []).append(rest)
    graph = load_graph(args.graph)
    faults = dict(parse_fault(text, graph) for text in args.fault)
    return Options(faults=faults, graph=args.graph, params=args.params, namespace=args.namespace,
                   use_sim_time=args.use_sim_time == 'true', time_factor=args.time_factor,
                   record_integrity=args.record_integrity, world=args.world,
                   domain_id=args.domain_id, bag=args.bag, respawn=args.respawn,
                   layout=args.layout, extra=extra, log_dir=args.log_dir,
                   realtime=args.realtime)


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-launch."""
    args = build_parser().parse_args(argv)
    try:
        launch = Launch(options_from(args))
    except GraphError as exc:
        print(f'agv-launch: {exc}', file=sys.stderr)
        return 2
    print(f'agv-launch: graph {launch.graph.name}, ROS_DOMAIN_ID={launch.domain}, '
          f'{len(launch.specs())} processes', flush=True)
    return launch.run(args.duration)


if __name__ == '__main__':
    sys.exit(main())
