"""Live-graph benchmark: the nine processes over DDS at a given time factor.

Runs the demo graph with the recorder for a while with the truck cruising (task
"srm at 1 angle 15" keeps it moving), samples each process's CPU from /proc, then reads the
bag: the ADC rate held at the position sensor (its own sample counter in
position_sensor_status, against the world's 340 Hz), snapshots lost (counter gaps), and the
worst gaps of the records that carry the control loop. Also times the lock-step harness on
the whole demonstration programme (real-time factor without DDS).

With --baseline REF the lock-step timing runs side by side: the programme in a fresh process
on this tree and on commit REF's agv_nodes (git archive into a temporary directory), the two
alternated --rounds times so that both see the same machine, the best of each kept; the seeded
runs' events, tasks and stop errors are compared (bench/lockstep_fingerprint.py).

Run: .venv/bin/python bench/graph_bench.py [--seconds 30] [--time-factor 1.0] [-p NODE:NAME:=V]
     [--no-live] [--baseline REF [--rounds 3]]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys
import tempfile
import time

from lockstep_fingerprint import first_difference

from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch
from agv_nodes.harness import DEMO_PROGRAMME, submit, truck

BENCH = Path(__file__).resolve().parent
# One timed run of the programme on the agv_nodes of the tree it is started in (cwd).
TIMED_RUN = ('import json, sys\n'
             f'sys.path.insert(1, {str(BENCH)!r})\n'
             'from lockstep_fingerprint import timed_fingerprint\n'
             'fp, wall, cpu = timed_fingerprint()\n'
             'print(json.dumps({"fp": fp, "wall": wall, "cpu": cpu}))\n')


def cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def live(seconds: float, time_factor: float, params: list[str] = (),
         wall_time: bool = False) -> None:
    out = Path(tempfile.mkdtemp(prefix='agv_graph_bench_'))
    extra: dict[str, list[str]] = {}
    for spec in params:  # NODE:NAME:=VALUE, as agv-launch -p
        node, _, arg = spec.partition(':')
        extra.setdefault(node, []).append(arg)
    launch = Launch(Options(time_factor=time_factor, bag=out / 'bag', quiet=True, extra=extra,
                            use_sim_time=not wall_time))
    launch.join()
    import rclpy
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.demo import comms_handshake

    rclpy.init()
    node = rclpy.create_node('graph_bench')
    pub = node.create_publisher(String, 'comms/task', qos.EVENTS)
    lines: list[str] = []
    node.create_subscription(String, 'comms/report', lambda m: lines.append(m.data), qos.EVENTS)
    launch.start()
    while not launch.moving.is_set() or pub.get_subscription_count() == 0:
        rclpy.spin_once(node, timeout_sec=0.1)
    comms_handshake(lambda: rclpy.spin_once(node, timeout_sec=0.05),
                    lambda text: pub.publish(String(data=text)), lines)
    pub.publish(String(data='srm at 1 angle 15'))
    time.sleep(3.0)
    c0 = {n: cpu_seconds(p.pid) for n, p in launch.procs.items()}
    t0 = time.monotonic()
    time.sleep(seconds)
    c1 = {n: cpu_seconds(p.pid) for n, p in launch.procs.items()}
    wall = time.monotonic() - t0
    node.destroy_node()
    rclpy.try_shutdown()
    launch.stop()
    clock = 'wall time, no /clock' if wall_time else 'sim time'
    print(f'Live graph, time_factor {time_factor:g}, {clock}, {seconds:.0f} s measured\n')
    print('| process | CPU (% of one core) |\n|---|---|')
    for name in sorted(c0, key=lambda n: c0[n] - c1[n]):
        print(f'| {name} | {100 * (c1[name] - c0[name]) / wall:.1f} |')
    print(f'| all | {100 * sum(c1[n] - c0[n] for n in c0) / wall:.1f} |')
    from agv_nodes.report import read_bag

    data = read_bag(out / 'bag')
    adc = data['records']['adc_snapshot']
    # records while snapshots came: on the wall clock the nodes write from start-up, before
    # the world moves (those seconds would count as lost, start-up's gaps as the graph's)
    status = [(t, f) for t, f in data['records']['position_sensor_status']
              if adc[0][0] <= t <= adc[-1][0]]
    counts = [f['sample_count'] for _t, f in status]
    times = [t for t, _f in status]
    processed = (counts[-1] - counts[0]) % 65536
    sim_span = adc[-1][0] - adc[0][0]
    published = len(adc)
    print('\n| measure | value |\n|---|---|')
    print(f'| simulated seconds recorded | {sim_span:.1f} |')
    print(f'| achieved real-time factor | {sim_span / (wall + 3.0):.2f} (asked {time_factor:g})'
          ' |')
    print(f'| ADC snapshots published (bag) per sim s | {published / sim_span:.1f} |')
    rate = processed / (times[-1] - times[0])
    print(f'| ADC snapshots processed by position_sensor per sim s | {rate:.1f} |')
    lost = max(0, round(published * (times[-1] - times[0]) / sim_span) - processed)
    print(f'| snapshots not processed (lost) | {lost} ({100 * lost / max(published, 1):.2f} %)'
          ' |')
    for record in ('traction_drive', 'traction_link', 'position_sensor_status',
                   'navigation_status', 'steering_command'):
        ts = [t for t, _f in data['records'][record] if adc[0][0] <= t <= adc[-1][0]]
        gaps = sorted(b - a for a, b in zip(ts, ts[1:], strict=False))
        p99 = gaps[int(0.99 * (len(gaps) - 1))]
        print(f'| {record} interval p50 / p99 / max (ms, sim) | '
              f'{1000 * statistics.median(gaps):.1f} / {1000 * p99:.1f} / '
              f'{1000 * gaps[-1]:.1f} |')


def lockstep() -> None:
    h = truck('demo_1983', seed=1)
    for text in DEMO_PROGRAMME:
        submit(h, text)
    comms, ex = h.cores['communications'], h.cores['executive']
    t0 = time.perf_counter()
    while comms.queue or ex.mode == 'running':
        h.step()
    wall = time.perf_counter() - t0
    print('\n| lock-step harness, whole demonstration programme | value |\n|---|---|')
    print(f'| simulated | {h.now:.1f} s |\n| wall | {wall:.1f} s |\n'
          f'| real-time factor | {h.now / wall:.1f}x |')
    where_the_time_goes()


def timed_run(tree: Path) -> dict:
    """Run the programme once in a fresh process on `tree`'s agv_nodes: fingerprint and times."""
    env = {**os.environ, 'PYTHONPATH': str(tree)}
    done = subprocess.run([sys.executable, '-c', TIMED_RUN], cwd=tree, env=env, check=True,
                          capture_output=True, text=True, timeout=900)
    return json.loads(done.stdout.strip().splitlines()[-1])


def side_by_side(baseline: str, rounds: int) -> None:
    """Time the programme on commit `baseline` and on this tree, alternated; compare results."""
    here = BENCH.parent
    with tempfile.TemporaryDirectory(prefix='agv_baseline_') as tmp:
        archive = subprocess.run(['git', 'archive', baseline], cwd=here, check=True,
                                 capture_output=True, timeout=120).stdout
        subprocess.run(['tar', '-x', '-C', tmp], input=archive, check=True, timeout=120)
        # its C kernels too, as its install would build them (optional: none to build, or no
        # compiler, leaves its Python code)
        subprocess.run([sys.executable, 'setup.py', '-q', 'build_ext', '--inplace'], cwd=tmp,
                       check=False, capture_output=True, timeout=600)
        commit = subprocess.run(['git', 'rev-parse', '--short', baseline], cwd=here, check=True,
                                capture_output=True, text=True, timeout=60).stdout.strip()
        trees = {f'commit {commit}': Path(tmp), 'this tree': here}
        runs: dict[str, list[dict]] = {name: [] for name in trees}
        for _ in range(rounds):
            for name, tree in trees.items():
                runs[name].append(timed_run(tree))
    best = {name: min(rs, key=lambda r: r['wall']) for name, rs in runs.items()}
    names = list(trees)
    print(f'\n| lock-step harness, whole programme (best of {rounds}) | '
          + ' | '.join(names) + ' |\n|---|' + '---|' * len(names))
    sim = {n: best[n]['fp']['simulated_s'] for n in names}
    print('| simulated (s) | ' + ' | '.join(f'{sim[n]:.1f}' for n in names) + ' |')
    print('| wall (s) | ' + ' | '.join(f'{best[n]["wall"]:.2f}' for n in names) + ' |')
    print('| real-time factor | '
          + ' | '.join(f'{sim[n] / best[n]["wall"]:.1f}x' for n in names) + ' |')
    print('| CPU per simulated s (ms) | '
          + ' | '.join(f'{1e3 * best[n]["cpu"] / sim[n]:.1f}' for n in names) + ' |')
    old, new = names
    print(f'| speed-up, wall | 1 | {best[old]["wall"] / best[new]["wall"]:.2f}x |')
    difference = first_difference(best[old]['fp'], best[new]['fp'])
    same = 'yes' if difference is None else f'no: first at {difference}'
    print(f'| same events, tasks and stop errors | - | {same} |')


def where_the_time_goes(seconds: float = 60.0) -> None:
    """Print the wall time per simulated second by part, over the programme's first minute.

    Timers go around the world's step and each core's calls; the rest is the harness's delivery
    and the codec. That is what a real-time factor of 100 (10 ms a simulated second) would have
    to fit in.
    """
    h = truck('demo_1983', seed=1)
    for text in DEMO_PROGRAMME:
        submit(h, text)
    spent: dict[str, float] = {}
    records = [0]

    def timed(obj: object, name: str, part: str) -> None:
        call = getattr(obj, name)

        def wrapper(*args: object) -> object:
            t = time.perf_counter()
            try:
                return call(*args)
            finally:
                spent[part] = spent.get(part, 0.0) + time.perf_counter() - t
        setattr(obj, name, wrapper)

    w = h.world
    timed(w.vehicle, 'step', 'world: vehicle dynamics')
    timed(w.sensor, 'snapshot', 'world: marker sensor optics + ADC')
    timed(w, 'step', 'world: all')
    for name, core in h.cores.items():
        timed(core, 'on_record', f'core: {name}')
        timed(core, 'tick', f'core: {name}')
    h.taps.append(lambda *_: records.__setitem__(0, records[0] + 1))
    t0 = time.perf_counter()
    h.run(seconds)
    wall = time.perf_counter() - t0
    cores = sum(v for k, v in spent.items() if k.startswith('core: '))
    rest = wall - spent['world: all'] - cores
    print(f'\n| part, first {seconds:g} s of the programme | ms per simulated s |\n|---|---|')
    rows = sorted(spent.items(), key=lambda kv: -kv[1])
    for part, value in rows:
        print(f'| {part} | {value / seconds * 1e3:.1f} |')
    print(f'| harness delivery + codec ({records[0] / seconds:.0f} records/s packed, '
          f'decoded once, each reader checking its sequence) | {rest / seconds * 1e3:.1f} |')
    print(f'| all (timers included) | {wall / seconds * 1e3:.1f} |')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seconds', type=float, default=30.0)
    ap.add_argument('--time-factor', type=float, default=1.0)
    ap.add_argument('--wall-time', action='store_true',
                    help='every node on the wall clock (use_sim_time false, no /clock: the '
                    'hardware configuration); the world paces itself at time factor 1')
    ap.add_argument('--no-live', action='store_true')
    ap.add_argument('--no-harness', action='store_true')
    ap.add_argument('--baseline', metavar='REF',
                    help='also time the lock-step programme on this commit, side by side')
    ap.add_argument('--rounds', type=int, default=3, help='alternated runs per tree (--baseline)')
    ap.add_argument('-p', '--param', action='append', default=[],
                    help='NODE:NAME:=VALUE for one node, e.g. recorder:poll_period:=0')
    args = ap.parse_args()
    if not args.no_live:
        live(args.seconds, args.time_factor, args.param, args.wall_time)
    if not args.no_harness and args.baseline:
        side_by_side(args.baseline, args.rounds)
        where_the_time_goes()
    elif not args.no_harness:
        lockstep()
    return 0


if __name__ == '__main__':
    sys.exit(main())
