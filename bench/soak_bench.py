"""Soak: the demonstration programme looped for an hour in lock step and 20 minutes over DDS.

The programme (agv_nodes.harness.DEMO_PROGRAMME) does not leave the room as it found it: it
ends with the truck resting at W2.2, and it has moved W0's load to W2 and W1's load to W3
(stations W0 and W1 hold one load each, W3 takes one). Submitted again as it is, its first
task would find no load at W0. So one loop is the programme followed by RETURN_TASKS, three
tasks of the same language that carry the two loads back (W3 to W1 by the fig 3.1 transfer,
then W2 to W0), in the order of the circuit so that they need the fewest laps. After a loop
the stations and the truck's conveyors are as at the start, and the truck rests at W0.1, not
at its start point 5.3 m upstream on the same wire. A lead-in task sent once before the first
loop (`stop at 0`) puts it there too, so every loop starts from the same state and runs the
same route (~820 simulated s); without it the first loop would be a lap shorter and its
event-driven records (traction_link, traction_drive) 2-4 % off the others' rates.

`--quick` loops QUICK_LOOP instead: the programme's two tasks that move no load (task 3, wait
at L0, and task 6, stop at W2.1 then W2.2), after the lead-in `stop at 2 second`. They leave
the room as they found them and the truck where the loop ends, one lap (~134 simulated s) each.

Each run loops whole loops until at least the asked simulated time has passed, and checks:

- no fault: every task completed (no FAILED or rejected report), no node died, no warning or
  error from a core (lock step) or ERROR row on /diagnostics (DDS), no rest away from a stop
  marker and no world event lost, no record rejected by a reader;
- every stop within STOP_TOLERANCE_MM of its stop marker's centre (the README's 15 mm; world
  ground truth, the final rest of each stop as agv-report counts it);
- memory flat: the RSS (/proc/<pid>/status VmRSS) of every node process (DDS) and of this
  process (lock step), sampled every SAMPLE_EVERY_S s of wall time, grows less than
  RSS_GROWTH_LIMIT_PCT from the end of the first programme (the warm-up) to the end. If the
  lock-step process grows past it, one more loop runs under tracemalloc and the lines that
  allocated most are listed;
- record rates steady: each record topic's rate over each loop (records per simulated s: sent,
  in lock step, from the harness's taps; over DDS each reader's accepted count from its
  /diagnostics inputs row, over the rows' own sim stamps) stays within RATE_BOUND_PCT of its
  mean over the loops, and the heartbeats of HEARTBEATS within HEARTBEAT_BOUND_PCT (why they
  get more is at HEARTBEATS).

Writes bench/results/soak_bench.md (not with --quick unless --output is given) and exits 1
when a check fails.

Run: .venv/bin/python bench/soak_bench.py [--lockstep-seconds 3600] [--dds-seconds 1200]
     [--quick] [--output F] [--domain-id N] [--no-bag]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
import gc
import os
from pathlib import Path
import shutil
import sys
import tempfile
import textwrap
import time
import tracemalloc
from typing import Any

from agv_nodes.harness import DEMO_PROGRAMME, Harness, submit, truck
from agv_nodes.report import final_stops

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / 'bench' / 'results' / 'soak_bench.md'

# W3's load back to W1 (the truck passes W3 before W1 from where the programme leaves it), then
# W2's back to W0; both use the first conveyor, the only one W0, W1 and W3 line up with.
RETURN_TASKS = ('load A at 3 and take to 1', 'load at 2 then continue', 'unload at 0')


@dataclass(frozen=True)
class LoopSpec:
    """What a run loops: programmes sent one after the other, after a lead-in sent once."""

    name: str
    lead_in: tuple[str, ...]  # brings the truck from its start to where each loop ends
    programmes: tuple[tuple[str, ...], ...]

    @property
    def tasks(self) -> int:
        """Tasks in one loop."""
        return sum(len(p) for p in self.programmes)


FULL_LOOP = LoopSpec('programme + return', ('stop at 0',), (DEMO_PROGRAMME, RETURN_TASKS))
QUICK_LOOP = LoopSpec('the quick loop', ('stop at 2 second',),
                      ((DEMO_PROGRAMME[3], DEMO_PROGRAMME[7]),))

STOP_TOLERANCE_MM = 15  # README: every stop within 15 mm of its stop marker's centre
RSS_GROWTH_LIMIT_PCT = 5.0
SAMPLE_EVERY_S = 2.0  # wall seconds between RSS samples
# Every record but HEARTBEATS is written on a fixed schedule (the sensor and wheel streams, the
# executive's commands, the periodic statuses), or on it plus one at each change that is the
# same in every loop (traction_link, traction_drive); over whole loops each rate held to
# 0.03 % of its mean in lock step (5 loops) and 0.1 % over DDS: 1 % is the claim.
RATE_BOUND_PCT = 1.0
# Navigation, traction and route status and navigation's position_sensor_command are sent when
# `now >= next` and then `next = now + period` (e.g. agv_nodes/navigation/core.py, tick): the
# 50 ms heartbeat waits for the first 10 ms tick at or after its due time, and whether the
# tick exactly 50 ms later counts as due depends on the rounding of the sim-time floats. Each
# interval is 50 ms or one tick more, in stretches that follow the truck's sim time, so the
# rate over a loop lies anywhere in 16.7-20 /s: in lock step 18.0-20.1 /s over whole loops
# (+-6.4 % about their mean); over DDS, where timers follow /clock's 8.8 ms steps, 18.3-18.4.
HEARTBEATS = ('navigation_status', 'traction_status', 'route_status', 'position_sensor_command')
HEARTBEAT_BOUND_PCT = 10.0


# -- what a run keeps --------------------------------------------------------------------------
def rss_kib(pid: int) -> int | None:
    """Return a process's resident set (VmRSS, KiB), None when it is gone."""
    try:
        text = Path(f'/proc/{pid}/status').read_text()
    except OSError:
        return None
    for line in text.splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    return None


class RssSampler:
    """RSS of a set of processes, sampled every `every` wall seconds, with labelled marks."""

    def __init__(self, pids: dict[str, int], every: float = SAMPLE_EVERY_S) -> None:
        self.pids = dict(pids)
        self.every = every
        self.samples: dict[str, list[tuple[float, float, int]]] = {n: [] for n in pids}
        self.marks: dict[str, dict[str, int]] = {}  # label -> process -> sample index
        self._t0 = time.monotonic()
        self._due = 0.0

    def sample(self, sim: float) -> None:
        """Take one sample of every process now (wall s since start, sim s, KiB)."""
        now = time.monotonic()
        for name, pid in self.pids.items():
            kib = rss_kib(pid)
            if kib is not None:
                self.samples[name].append((now - self._t0, sim, kib))
        self._due = now + self.every

    def poll(self, sim: float) -> None:
        """Sample if the interval has passed."""
        if time.monotonic() >= self._due:
            self.sample(sim)

    def mark(self, label: str, sim: float) -> None:
        """Sample now and remember this sample as `label`."""
        self.sample(sim)
        self.marks[label] = {n: len(s) - 1 for n, s in self.samples.items() if s}

    def growth(self, since: str = 'warm-up') -> dict[str, dict[str, float]]:
        """Per process: RSS at the mark, at the end and its peak after it (KiB); growth %."""
        out = {}
        for name, samples in self.samples.items():
            i = self.marks.get(since, {}).get(name)
            if i is None:
                continue
            warm, end = samples[i][2], samples[-1][2]
            out[name] = {'warm_kib': warm, 'end_kib': end,
                         'peak_kib': max(s[2] for s in samples[i:]),
                         'growth_pct': 100.0 * (end - warm) / warm,
                         'samples': len(samples) - i}
        return out


@dataclass
class Loop:
    """One loop of a run."""

    sim_start: float
    sim_end: float = 0.0
    wall_s: float = 0.0
    tasks: list[tuple[str, str]] = field(default_factory=list)  # (text, outcome)
    rates: dict[str, float] = field(default_factory=dict)  # topic key -> records / sim s


@dataclass
class Soak:
    """A whole run: its loops, stops, memory, faults and what else it noticed."""

    mode: str
    asked_s: float
    spec: LoopSpec
    lead_in: Loop | None = None
    loops: list[Loop] = field(default_factory=list)
    stops: list[dict[str, Any]] = field(default_factory=list)
    memory: dict[str, dict[str, float]] = field(default_factory=dict)
    faults: list[str] = field(default_factory=list)
    lost: dict[str, int] = field(default_factory=dict)  # DDS: counter gaps by topic key
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    sim_s: float = 0.0

    def tasks_completed(self) -> tuple[int, int]:
        """Return (completed, run)."""
        runs = ([self.lead_in] if self.lead_in else []) + self.loops
        outcomes = [o for loop in runs for _t, o in loop.tasks]
        return sum(o == 'completed' for o in outcomes), len(outcomes)


def rate_bound(key: str) -> float:
    """Return the bound (% of the mean over the loops) for a topic key 'record[>reader]'."""
    return HEARTBEAT_BOUND_PCT if key.split('>')[0] in HEARTBEATS else RATE_BOUND_PCT


def rate_spread(rates: Sequence[float]) -> float:
    """Return the largest deviation of a rate from the mean of the loops, % of the mean."""
    mean = sum(rates) / len(rates)
    return 100.0 * max(abs(r - mean) for r in rates) / mean if mean else 0.0


def checks(soak: Soak, rss_limit_pct: float = RSS_GROWTH_LIMIT_PCT
           ) -> list[tuple[str, bool, str]]:
    """Return each check as (what, passed, detail)."""
    out = []
    done, run = soak.tasks_completed()
    out.append(('every task completed', run > 0 and done == run, f'{done}/{run}'))
    out.append(('no fault', not soak.faults, f'{len(soak.faults)} faults' if soak.faults
                else 'none'))
    errors = [s['error_mm'] for s in soak.stops]
    worst = max((abs(e) for e in errors), default=0)
    out.append((f'stops within {STOP_TOLERANCE_MM} mm', bool(errors)
                and worst <= STOP_TOLERANCE_MM, f'{len(errors)} stops, worst {worst} mm'))
    grown = {n: m['growth_pct'] for n, m in soak.memory.items()}
    big = {n: g for n, g in grown.items() if g >= rss_limit_pct}
    out.append((f'RSS growth after warm-up < {rss_limit_pct:g} %', bool(grown) and not big,
                ', '.join(f'{n} {g:+.1f} %' for n, g in big.items())
                or f'largest {max(grown.values(), default=0):+.2f} %'))
    if len(soak.loops) < 2:
        out.append(('record rates steady between loops', False,
                    f'{len(soak.loops)} loop: nothing to compare'))
    else:
        keys = sorted(set.intersection(*(set(loop.rates) for loop in soak.loops)))
        over = []
        for key in keys:
            spread = rate_spread([loop.rates[key] for loop in soak.loops])
            if spread >= rate_bound(key):
                over.append(f'{key} +-{spread:.2f} %')
        out.append((f'record rates steady between loops (+-{RATE_BOUND_PCT:g} %, heartbeats '
                    f'+-{HEARTBEAT_BOUND_PCT:g} %)', bool(keys) and not over,
                    ', '.join(over) or f'{len(keys)} topics'))
    return out


# -- lock step ---------------------------------------------------------------------------------
def _run_programme(h: Harness, texts: Sequence[str], sampler: RssSampler,
                   sim_limit: float) -> bool:
    """Submit `texts` and step until communications and the executive are idle (False: limit)."""
    comms, executive = h.cores['communications'], h.cores['executive']
    for text in texts:
        submit(h, text)
    end = h.now + sim_limit
    steps = 0
    while comms.queue or executive.mode == 'running':
        h.step()
        steps += 1
        if steps % 340 == 0:
            sampler.poll(h.now)
            if h.now > end:
                return False
    return True


def _lockstep_loop(h: Harness, loop: Sequence[Sequence[str]], soak: Soak,
                   sampler: RssSampler, counts: dict[str, int], first: bool) -> Loop:
    """Run the programmes of one loop in lock step; note their tasks, faults and rates."""
    comms = h.cores['communications']
    done = Loop(h.now)
    wall0, results0 = time.monotonic(), len(comms.results)
    counts.clear()
    for i, texts in enumerate(loop):
        if not _run_programme(h, texts, sampler, sim_limit=3000.0):
            soak.faults.append(f'{h.now:.1f} s: programme not finished in 3000 simulated s')
        if first and i == 0:
            sampler.mark('warm-up', h.now)
    done.sim_end, done.wall_s = h.now, time.monotonic() - wall0
    texts = [t for programme in loop for t in programme]
    for text, (_id, state, cause) in zip(texts, comms.results[results0:], strict=False):
        done.tasks.append((text, state if cause == 'none' else f'{state}: {cause}'))
        if state != 'completed':
            soak.faults.append(f'task {text!r}: {state} ({cause})')
    for text in texts[len(comms.results) - results0:]:
        done.tasks.append((text, 'not finished'))
    for name, core in h.cores.items():
        soak.faults += [f'{n.time:.1f} s: {name} {n.level}: {n.text}' for n in core.notes.take()
                        if n.level != 'info']
    level, why = h.cores['traction'].health()
    if level >= 2:
        soak.faults.append(f'{h.now:.1f} s: traction: {why}')
    span = done.sim_end - done.sim_start
    done.rates = {record: n / span for record, n in counts.items()}
    return done


def run_lockstep(seconds: float, spec: LoopSpec = FULL_LOOP, seed: int = 1,
                 progress: Callable[[str], None] = print, trace: bool = False) -> Soak:
    """Loop `spec` in lock step for at least `seconds` of simulated time (whole loops)."""
    soak = Soak('lock step', seconds, spec)
    h = truck('demo_1983', seed=seed)
    counts: dict[str, int] = {}

    def tap(record: str, _raw: bytes, _now: float) -> None:
        counts[record] = counts.get(record, 0) + 1

    h.taps.append(tap)
    sampler = RssSampler({'bench process (lock step)': os.getpid()})
    sampler.mark('start', 0.0)
    wall0 = time.monotonic()
    soak.lead_in = _lockstep_loop(h, (spec.lead_in,), soak, sampler, counts, False)
    while not soak.loops or h.now < seconds:
        soak.loops.append(_lockstep_loop(h, spec.programmes, soak, sampler, counts,
                                         not soak.loops))
        last = soak.loops[-1]
        progress(f'lock step: loop {len(soak.loops)} ended at {h.now:.0f} s sim '
                 f'({last.wall_s:.0f} s wall), RSS '
                 f'{sampler.samples["bench process (lock step)"][-1][2] / 1024:.1f} MiB')
    soak.wall_s, soak.sim_s = time.monotonic() - wall0, h.now
    sampler.mark('end', h.now)
    soak.memory = sampler.growth()
    soak.stops = final_stops(h.events)
    soak.faults += [f'{s["time"]:.1f} s: rest away from any stop marker' for s in soak.stops
                    if s['marker'] == '-']
    soak.stops = [s for s in soak.stops if s['marker'] != '-']
    soak.faults += [f'{record}>{m.core.node}: {reader.rejected} records rejected'
                    for m in h.members for record, reader in m.readers.items()
                    if reader.rejected]
    soak.notes.append(f'Python objects tracked by gc: {len(gc.get_objects())} at the end')
    grown = soak.memory.get('bench process (lock step)', {}).get('growth_pct', 0.0)
    if trace or grown >= RSS_GROWTH_LIMIT_PCT:
        soak.notes += traced_loop(h, spec.programmes, sampler)
    return soak


def traced_loop(h: Harness, loop: Sequence[Sequence[str]], sampler: RssSampler,
                top: int = 10) -> list[str]:
    """Run one more loop under tracemalloc; return the lines whose allocations grew most."""
    tracemalloc.start(3)
    before = tracemalloc.take_snapshot()
    for texts in loop:
        _run_programme(h, texts, sampler, sim_limit=3000.0)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    lines = [f'tracemalloc over one more loop, top {top} growths:']
    for stat in after.compare_to(before, 'lineno')[:top]:
        frame = stat.traceback[0]
        lines.append(f'{stat.size_diff / 1024:+.1f} KiB in {stat.count_diff:+d} blocks at '
                     f'{frame.filename}:{frame.lineno}')
    return lines


# -- over DDS ----------------------------------------------------------------------------------
def event_time(time_ms: int, reference: float) -> float:
    """Unwrap a world_event's 16-bit ms stamp to the sim time nearest `reference`."""
    ref_ms = round(reference * 1000)
    return (ref_ms + (time_ms - ref_ms + 32768) % 65536 - 32768) / 1000


def rates_between(rows0: dict[str, tuple[float, dict[str, str]]],
                  rows1: dict[str, tuple[float, dict[str, str]]],
                  what: str = 'accepted') -> dict[str, float]:
    """'record>node' -> per sim s of `what`, between two snapshots of the inputs rows."""
    out = {}
    for node, (t1, values1) in rows1.items():
        if node not in rows0 or t1 <= rows0[node][0]:
            continue
        t0, values0 = rows0[node]
        for key, value in values1.items():
            if key.endswith(f' {what}') and key in values0:
                record = key[:-len(what) - 1]
                out[f'{record}>{node}'] = (int(value) - int(values0[key])) / (t1 - t0)
    return out


def counts_between(rows0: dict[str, tuple[float, dict[str, str]]],
                   rows1: dict[str, tuple[float, dict[str, str]]],
                   what: str) -> dict[str, int]:
    """'record>node' -> how much `what` (e.g. 'lost (counter gaps)') grew between snapshots."""
    out = {}
    suffix = f' {what}'
    for node, (_t1, values1) in rows1.items():
        values0 = rows0.get(node, (0.0, {}))[1]
        for key, value in values1.items():
            if key.endswith(suffix) and value.isdigit():
                record = key[:-len(suffix)]
                out[f'{record}>{node}'] = int(value) - int(values0.get(key, '0'))
    return out


class _Watch:
    """The bench's rclpy node on the graph's domain: reports, events, diagnostics, sim time."""

    def __init__(self, domain: int) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        import rclpy
        from rclpy.context import Context
        from std_msgs.msg import String

        from agv_nodes import qos
        from agv_nodes.records.codec import codec
        from agv_nodes.ros_ports import RecordSubscription

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node('soak_bench', context=self.context)
        try:  # one events executor for the whole run, as agv-demo: it costs the graph least
            from rclpy.experimental import EventsExecutor

            self.executor = EventsExecutor(context=self.context)
        except ImportError:
            self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.sim = 0.0
        self.reports: list[tuple[float, str]] = []  # (sim s, line) of comms/report
        self.lines: list[str] = []  # the same lines alone (agv_nodes.demo.comms_handshake)
        self.events: list[dict[str, Any]] = []
        self.events_lost = 0
        self._count: int | None = None
        self.rows: dict[str, tuple[float, dict[str, str]]] = {}  # node -> (sim stamp, values)
        self.errors: list[tuple[float, str, str]] = []
        n = self.node
        n.create_subscription(PoseStamped, 'world/pose', self._pose, qos.STREAM_READER)
        n.create_subscription(String, 'comms/report', self._report, qos.EVENTS)
        n.create_subscription(DiagnosticArray, '/diagnostics', self._diagnostics, qos.EVENTS)
        self._events = RecordSubscription(n, codec()['world_event'], 'none', self._event)
        self.task_pub = n.create_publisher(String, 'comms/task', qos.EVENTS)

    def _pose(self, msg: Any) -> None:
        self.sim = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    def _report(self, msg: Any) -> None:
        self.reports.append((self.sim, msg.data))
        self.lines.append(msg.data)

    def _event(self, fields: dict[str, Any]) -> None:
        if self._count is not None:
            self.events_lost += (fields['count'] - self._count - 1) % 256
        self._count = fields['count']
        self.events.append({**fields, 'time': event_time(fields['time_ms'], self.sim)})

    def _diagnostics(self, msg: Any) -> None:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        for st in msg.status:
            level = st.level if isinstance(st.level, int) else int.from_bytes(st.level, 'little')
            if level >= 2:
                self.errors.append((self.sim, st.name, st.message))
            if st.name.endswith('/inputs'):
                self.rows[st.hardware_id] = (stamp, {kv.key: kv.value for kv in st.values})

    def send(self, text: str) -> None:
        """Put one line on comms/task."""
        from std_msgs.msg import String

        self.task_pub.publish(String(data=text))

    def spin(self, timeout: float = 0.1) -> None:
        """Take what has come."""
        self.executor.spin_once(timeout_sec=timeout)

    def close(self) -> None:
        """Leave the graph."""
        import rclpy

        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)


FINAL = ('completed', 'FAILED', 'rejected')


def _finals(reports: Sequence[tuple[float, str]]) -> list[tuple[str, str, str]]:
    """(task text, outcome, '<sim s> s: <line>') for each final report on comms/report."""
    out = []
    for t, line in reports:
        words = line.split()
        if line.startswith('comms: rejected'):
            out.append((line, 'rejected', f'{t:.1f} s: {line}'))
        elif len(words) > 2 and words[0] == 'task' and words[1].isdigit():
            for final in FINAL:
                if f': {final}' in line:
                    text = line.split("'")[1] if "'" in line else line
                    out.append((text, final.lower() if final != 'completed' else final,
                                f'{t:.1f} s: {line}'))
    return out


def _await_finals(watch: _Watch, sampler: RssSampler, alive: Callable[[], bool], since: int,
                  count: int, stall_s: float) -> list[tuple[str, str, str]]:
    """Spin until `count` final reports have come after report `since`.

    Returns early (with fewer) when a node dies or sim time stands still for `stall_s` wall s.
    """
    last_sim, last_move = watch.sim, time.monotonic()
    while len(finals := _finals(watch.reports[since:])) < count:
        watch.spin()
        sampler.poll(watch.sim)
        if not alive():
            break
        if watch.sim != last_sim:
            last_sim, last_move = watch.sim, time.monotonic()
        elif time.monotonic() - last_move > stall_s:
            break
    return finals


def run_dds(seconds: float, spec: LoopSpec = FULL_LOOP, out: Path | None = None,
            domain_id: int | None = None, bag: bool = True,
            progress: Callable[[str], None] = print, stall_s: float = 90.0) -> Soak:
    """Launch the graph and loop `spec` over DDS for at least `seconds` of simulated time.

    One process per node (agv_nodes.graph.supervisor.Launch, time factor 0: as fast as the
    graph keeps up), the recorder too unless `bag` is False. Logs (and the bag) go to `out`,
    or to a temporary directory removed afterwards when the run had no fault.
    """
    from agv_nodes.demo import comms_handshake, silent_links
    from agv_nodes.graph.parameters import Options, wait_links
    from agv_nodes.graph.supervisor import Launch

    soak = Soak('DDS', seconds, spec)
    own = out is None
    out = Path(tempfile.mkdtemp(prefix='agv_soak_')) if out is None else Path(out)
    launch = Launch(Options(time_factor=0.0, bag=out / 'bag' if bag else None, quiet=True,
                            log_dir=out / 'logs', domain_id=domain_id))
    launch.join()
    watch = _Watch(launch.domain)
    progress(f'DDS: {len(launch.specs())} processes on ROS_DOMAIN_ID={launch.domain}; '
             f'logs in {out / "logs"}')
    launch.start()
    sampler = RssSampler({name: proc.pid for name, proc in launch.procs.items()})
    wall0 = time.monotonic()

    def alive() -> bool:
        dead = launch.poll()
        if dead:
            soak.faults.append(f'{watch.sim:.1f} s: node(s) died: {", ".join(dead)}')
        return not launch.failed

    def wait(condition: Callable[[], bool], limit: float, what: str) -> None:
        deadline = time.monotonic() + limit
        while not condition():
            watch.spin()
            sampler.poll(watch.sim)
            if not alive() or time.monotonic() > deadline:
                raise RuntimeError(f'no {what} within {limit:.0f} s')

    try:
        wait(lambda: launch.moving.is_set() and watch.task_pub.get_subscription_count() > 0,
             120, 'graph moving')
        comms_handshake(lambda: watch.spin(0.05), watch.send, watch.lines, alive=alive)
        links = wait_links(launch.graph, recording=bag)
        wait(lambda: not silent_links(links, {n: {k[:-len(' accepted')]: int(v)
                                                  for k, v in vals.items()
                                                  if k.endswith(' accepted')}
                                              for n, (_t, vals) in watch.rows.items()},
                                          launch.silent_records),
             60, 'record on every link')
        progress(f'DDS: graph up in {time.monotonic() - wall0:.1f} s; looping from '
                 f'{watch.sim:.1f} s sim')
        sim0, moving_wall = watch.sim, time.monotonic()
        first_rows = dict(watch.rows)
        sampler.mark('start', watch.sim)
        seen = [len(watch.reports)]
        broken = [False]  # a node died or time stood still: the run cannot go on

        def run_loop(programmes: Sequence[Sequence[str]], first: bool) -> Loop:
            done = Loop(watch.sim)
            rows0, loop_wall = dict(watch.rows), time.monotonic()
            for i, texts in enumerate(programmes):
                for text in texts:
                    watch.send(text)
                finals = _await_finals(watch, sampler, alive, seen[0], len(texts), stall_s)
                seen[0] = len(watch.reports)
                done.tasks += [(text, outcome) for text, outcome, _line in finals]
                soak.faults += [line for _text, outcome, line in finals
                                if outcome != 'completed']
                if len(finals) < len(texts):
                    if not launch.failed:
                        soak.faults.append(f'{watch.sim:.1f} s: sim time stood still for '
                                           f'{stall_s:.0f} s of wall time')
                    broken[0] = True
                    break
                if first and i == 0:
                    sampler.mark('warm-up', watch.sim)
            done.sim_end, done.wall_s = watch.sim, time.monotonic() - loop_wall
            done.rates = rates_between(rows0, dict(watch.rows))
            return done

        soak.lead_in = run_loop((spec.lead_in,), False)
        # A failed task does not end the run: the soak goes on measuring, and the room is as
        # it should be again after at most one more loop (a load left where it was is fetched
        # by the next loop's task).
        while not broken[0] and (not soak.loops or watch.sim - sim0 < seconds):
            soak.loops.append(run_loop(spec.programmes, not soak.loops))
            progress(f'DDS: loop {len(soak.loops)} ended at {watch.sim - sim0:.0f} s sim '
                     f'({soak.loops[-1].wall_s:.0f} s wall); RSS MiB '
                     + ', '.join(f'{n} {s[-1][2] / 1024:.0f}'
                                 for n, s in sampler.samples.items() if s))
        soak.sim_s, soak.wall_s = watch.sim - sim0, time.monotonic() - moving_wall
        sampler.mark('end', watch.sim)
        # a second of wall time for the events of the last stop to arrive
        settle = time.monotonic() + 1.0
        while time.monotonic() < settle:
            watch.spin(0.1)
        soak.lost = {k: v for k, v in counts_between(first_rows, watch.rows,
                                                     'lost (counter gaps)').items()}
        rejected = {k: v for k, v in counts_between(first_rows, watch.rows, 'rejected').items()
                    if v}
        soak.faults += [f'{k}: {v} records rejected' for k, v in rejected.items()]
        errors: dict[tuple[str, str], list[float]] = {}  # each row repeats once a second
        for t, name, msg in watch.errors:
            if t >= sim0:
                errors.setdefault((name, msg), []).append(t)
        soak.faults += [f'{ts[0]:.1f}-{ts[-1]:.1f} s: /diagnostics ERROR {name}: {msg} '
                        f'({len(ts)} rows)' for (name, msg), ts in errors.items()]
        if watch.events_lost:
            soak.faults.append(f'{watch.events_lost} world events lost')
        stops = final_stops([e for e in watch.events if e['time'] >= sim0])
        soak.faults += [f'{s["time"]:.1f} s: rest away from any stop marker' for s in stops
                        if s['marker'] == '-']
        soak.stops = [s for s in stops if s['marker'] != '-']
    except RuntimeError as exc:
        soak.faults.append(f'{watch.sim:.1f} s: {exc}')
        soak.sim_s, soak.wall_s = watch.sim, time.monotonic() - wall0
    finally:
        watch.close()
        launch.stop()
    soak.memory = sampler.growth()
    soak.faults += [f'{name} exited with status {code}' for name, code in launch.exits.items()
                    if code not in (0, None)]
    soak.faults += [f'{name} needed {sig} to stop' for name, sig in launch.escalated.items()]
    if own and not soak.faults:
        shutil.rmtree(out, ignore_errors=True)
    elif soak.faults:
        soak.notes.append(f'logs kept in {out / "logs"}')
    return soak


# -- the tables --------------------------------------------------------------------------------
def render(soak: Soak) -> list[str]:
    """Markdown of one run."""
    done, run = soak.tasks_completed()
    errors = [s['error_mm'] for s in soak.stops]
    stops = f'{min(errors):+d}..{max(errors):+d} ({len(errors)} stops)' if errors else '-'
    factor = soak.sim_s / soak.wall_s if soak.wall_s else 0.0
    lines = [f'## {soak.mode}: {soak.asked_s:g} simulated s asked', '',
             '| measure | value |', '|---|---|',
             f'| loops | {len(soak.loops)} of {soak.spec.name} ({soak.spec.tasks} tasks each, '
             f'after the lead-in {", ".join(map(repr, soak.spec.lead_in))}) |',
             f'| tasks run | {run} ({done} completed) |',
             f'| faults | {len(soak.faults)}{": " if soak.faults else ""}'
             f'{"; ".join(soak.faults[:6])}{"; ..." if len(soak.faults) > 6 else ""} |',
             f'| stop errors (mm past the centre) | {stops} |',
             f'| simulated / wall time | {soak.sim_s:.0f} s / {soak.wall_s:.0f} s |',
             f'| real-time factor | {factor:.2f} |', '',
             '| process | RSS at warm-up (MiB) | RSS at end (MiB) | growth | peak after '
             'warm-up (MiB) | samples |', '|---|---|---|---|---|---|']
    for name, m in sorted(soak.memory.items()):
        lines.append(f'| {name} | {m["warm_kib"] / 1024:.1f} | {m["end_kib"] / 1024:.1f} | '
                     f'{m["growth_pct"]:+.2f} % | {m["peak_kib"] / 1024:.1f} | '
                     f'{m["samples"]:.0f} |')
    if soak.loops:
        keys = sorted(set.intersection(*(set(loop.rates) for loop in soak.loops)))
        reader = 'reader' if soak.mode == 'DDS' else 'sent'
        lost = ' lost (counter gaps) |' if soak.lost else ''
        lines += ['', f'| record ({reader}) | rate min (/s) | rate max (/s) | spread '
                  f'(max from mean) | bound |{lost}',
                  '|---|---|---|---|---|' + ('---|' if lost else '')]
        for key in keys:
            rates = [loop.rates[key] for loop in soak.loops]
            cell = f' {soak.lost.get(key, 0)} |' if lost else ''
            lines.append(f'| {key.replace(">", " > ")} | {min(rates):.2f} | {max(rates):.2f} | '
                         f'+-{rate_spread(rates):.2f} % | +-{rate_bound(key):g} % |{cell}')
    lines += ['', '| loop | sim start (s) | sim (s) | wall (s) | tasks |', '|---|---|---|---|---|']
    for i, loop in enumerate(soak.loops, 1):
        ok = sum(o == 'completed' for _t, o in loop.tasks)
        lines.append(f'| {i} | {loop.sim_start:.0f} | {loop.sim_end - loop.sim_start:.0f} | '
                     f'{loop.wall_s:.0f} | {ok}/{len(loop.tasks)} completed |')
    lines += ['', '| check | result | detail |', '|---|---|---|']
    lines += [f'| {what} | {"pass" if ok else "FAIL"} | {detail} |'
              for what, ok, detail in checks(soak)]
    if soak.notes:
        lines += [''] + [f'- {note}' for note in soak.notes]
    return lines + ['']


def header(command: str, spec: LoopSpec, bag: bool, note: str = '') -> list[str]:
    """Markdown above the runs' tables."""
    if spec is FULL_LOOP:
        loop = ('the demonstration programme (`DEMO_PROGRAMME`, 8 tasks) and the three return '
                'tasks that carry its two loads back ('
                + ', '.join(f'`{t}`' for t in RETURN_TASKS) + '), so that the next loop finds '
                'the room as the first did')
    else:
        loop = ("the programme's two tasks that move no load ("
                + ', '.join(f'`{t}`' for t in spec.programmes[0]) + ')')
    lead_in = ', '.join(f'`{t}`' for t in spec.lead_in)
    paragraphs = [
        '# Soak: the demonstration programme looped (`bench/soak_bench.py`)', '',
        '```bash', command, '```', '', *([note, ''] if note else []),
        f'One loop is {loop}. A lead-in ({lead_in}) first brings the truck to where a loop '
        'ends, so every loop starts from the same state; then whole loops run until at least '
        'the asked simulated time has passed. The lock-step harness runs in this process; over '
        'DDS each node is its own process (`agv_nodes.graph.supervisor.Launch`, time factor 0, '
        f'recorder {"on" if bag else "off"}), tasks go on `comms/task`.', '',
        f'- **RSS**: VmRSS of each process, sampled every {SAMPLE_EVERY_S:g} s of wall time. '
        '**warm-up**: the end of the first programme of the first loop. **growth**: from '
        'warm-up to the end.',
        '- **rate**: records per simulated second over each loop; lock step: sent (harness '
        "taps); DDS: accepted by each reader (its `/diagnostics` inputs row, over the rows' "
        "sim stamps). **spread**: the largest deviation of a loop's rate from the mean over "
        'the loops. The four status heartbeats get a wider bound: each is sent at the first '
        'timer tick at or after 50 ms from the last one, and whether that is 50 ms or a tick '
        'more depends on the rounding of the sim-time floats (`HEARTBEATS` in the bench).',
        '- **stop errors**: world ground truth, the final rest of each stop (as agv-report '
        'counts stops).', '']
    return [textwrap.fill(p, 99, subsequent_indent='  ' if p.startswith('- ') else '',
                          break_on_hyphens=False) if len(p) > 99 else p for p in paragraphs]


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--lockstep-seconds', type=float, default=None,
                    help='simulated s in lock step (default 3600; --quick 600; 0 skips it)')
    ap.add_argument('--dds-seconds', type=float, default=None,
                    help='simulated s over DDS (default 1200; --quick 250; 0 skips it)')
    ap.add_argument('--quick', action='store_true',
                    help='loop the two tasks that move no load, for a short run')
    ap.add_argument('--output', type=Path,
                    help=f'write the tables here (default {RESULTS.relative_to(REPO)}, '
                    'not written with --quick)')
    ap.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID (default: a free one)')
    ap.add_argument('--no-bag', action='store_true', help='run the graph without the recorder')
    ap.add_argument('--trace', action='store_true',
                    help='run one lock-step loop more under tracemalloc even if RSS is flat')
    ap.add_argument('--note', default='', help='a line for the header (e.g. why shortened)')
    args = ap.parse_args(argv)
    lockstep_s = args.lockstep_seconds if args.lockstep_seconds is not None else (
        600.0 if args.quick else 3600.0)
    dds_s = args.dds_seconds if args.dds_seconds is not None else (
        250.0 if args.quick else 1200.0)
    loop = QUICK_LOOP if args.quick else FULL_LOOP
    command = '.venv/bin/python bench/soak_bench.py' + ''.join(
        f' {a}' for a in (sys.argv[1:] if argv is None else argv))
    lines = header(command, loop, not args.no_bag, args.note)
    passed = True
    for seconds, runner in ((lockstep_s, lambda s: run_lockstep(s, loop, trace=args.trace)),
                            (dds_s, lambda s: run_dds(s, loop, domain_id=args.domain_id,
                                                      bag=not args.no_bag))):
        if seconds <= 0:
            continue
        soak = runner(seconds)
        lines += render(soak)
        passed = passed and all(ok for _w, ok, _d in checks(soak))
    text = '\n'.join(lines)
    print(text)
    output = args.output or (None if args.quick else RESULTS)
    if output is not None:
        output.write_text(text)
    return 0 if passed else 1


if __name__ == '__main__':
    sys.exit(main())
