"""Sensor-to-traction latency from a recorded run, hop by hop, in sim time.

Run: .venv/bin/python bench/latency_bench.py BAG [BAG ...]
     (a bag of `agv-demo`, `bench/graph_bench.py` or `agv-launch --bag`)

The recorder stamps every message with the sim time at which it was *sent* (agv_nodes/recorder.py),
so the bag holds each hop of the chain the 1983 truck ran on a recognition:

1. ADC snapshot -> position_sensor_status: the status carries the count of snapshots processed,
   so the snapshot that completed it is known exactly (every status, heartbeats included);
2. a recognition (recognised = 1) -> the first traction_link navigation sends after it with new
   contents (PC6/1 asks for 20 % at its target location, and a controlled stop updates its
   distance to go at every stop view; other recognitions change nothing and are not counted);
3. that traction_link -> the first traction_drive traction sends after it (traction's START loop
   runs every 10 ms, so this is the loop's wait, not a measured reaction).

Sensor-to-traction is 1 + 2 + 3 for each recognition that changed the link. Under sim time every
node's clock moves in /clock steps (3 samples, 8.8 ms), which quantises hops 2 and 3 in a bag.

`--live` measures the same hops in wall time on a running graph instead (the "live graph
at real time"): it launches the graph (recorder included, as in the demo) at `--time-factor`,
runs the first `--tasks` tasks of the demonstration programme (default 2, the quick programme:
two stops and a landmark each), and a probe in this process
keeps every message's DDS source timestamp: the wall time its writer sent it, one host, one
clock, so the probe's own lag does not count. The probe reads the ADC at 340 Hz too (a load
the demo does not have).

Prints Markdown tables: n, p50, p99, max per hop, in ms (sim time from a bag, wall time live).
"""

from __future__ import annotations

import argparse
import bisect
import math
from pathlib import Path
import sys
import tempfile
import time

from agv_nodes.records import codec
from agv_nodes.records.carrier import uint8_array_data
from agv_nodes.report import record_integrity

TOPICS = {'/hw/position_sensor/adc': 'adc_snapshot',
          '/position_sensor/status': 'position_sensor_status',
          '/traction/link': 'traction_link', '/hw/traction/drive': 'traction_drive'}


def read(bag: Path) -> dict[str, list]:
    """Read a run's bag: sent times (s) of every ADC snapshot and traction_drive.

    Also (time, fields) of the statuses and links.
    """
    from rosbags.highlevel import AnyReader

    c = codec()
    out: dict[str, list] = {name: [] for name in TOPICS.values()}
    with AnyReader([bag]) as reader:
        conns = [x for x in reader.connections if x.topic in TOPICS]
        for conn, stamp, raw in reader.messages(connections=conns):
            name = TOPICS[conn.topic]
            t = stamp * 1e-9
            if name in ('adc_snapshot', 'traction_drive'):
                out[name].append(t)
                continue
            data = uint8_array_data(raw) or bytes(reader.deserialize(raw, conn.msgtype).data)
            out[name].append((t, c.decode(name, data, integrity=record_integrity(data))))
    return out


def hops(run: dict[str, list]) -> dict[str, list[float]]:
    """Latencies (s) per hop and for the whole chain."""
    adc, drive = run['adc_snapshot'], run['traction_drive']
    statuses, links = run['position_sensor_status'], run['traction_link']
    out: dict[str, list[float]] = {'adc_to_status': [], 'recognition_to_link': [],
                                   'link_to_drive': [], 'sensor_to_traction': []}
    count, last = 0, None
    processed: list[tuple[float, int]] = []  # (status time, unwrapped snapshot count)
    for t, f in statuses:
        n = f['sample_count']
        count = n if last is None else count + ((n - last) & 0xFFFF)
        last = n
        processed.append((t, count))
        if 0 < count <= len(adc) and not math.isnan(adc[count - 1]):
            out['adc_to_status'].append(t - adc[count - 1])
    link_times = [t for t, _f in links]
    for (t, f), (_t, count) in zip(statuses, processed, strict=True):
        if not f['recognised'] or not 0 < count <= len(adc) or math.isnan(adc[count - 1]):
            continue
        i = bisect.bisect_right(link_times, t)
        # the first link after the recognition; it counts when its contents are new
        if i >= len(links) or (i and links[i][1] == links[i - 1][1]) or links[i][0] - t > 0.2:
            continue
        j = bisect.bisect_right(drive, links[i][0])
        if j >= len(drive):
            continue
        sensor, link, out_drive = t - adc[count - 1], links[i][0] - t, drive[j] - links[i][0]
        out['recognition_to_link'].append(link)
        out['link_to_drive'].append(out_drive)
        out['sensor_to_traction'].append(sensor + link + out_drive)
    return out


def table(name: str, result: dict[str, list[float]]) -> str:
    def pct(values: list[float], q: float) -> float:
        s = sorted(values)
        return s[min(len(s) - 1, int(q * len(s)))] * 1000.0

    lines = [f'\n{name}\n', '| hop | n | p50 (ms) | p99 (ms) | max (ms) |',
             '|---|---|---|---|---|']
    for hop, values in result.items():
        if values:
            lines.append(f'| {hop.replace("_", " ")} | {len(values)} | {pct(values, 0.5):.1f} | '
                         f'{pct(values, 0.99):.1f} | {max(values) * 1000.0:.1f} |')
        else:
            lines.append(f'| {hop.replace("_", " ")} | 0 | - | - | - |')
    return '\n'.join(lines)


def align(run: dict[str, list]) -> dict[str, list]:
    """Put a gap (NaN) where the probe missed snapshots the position sensor counted.

    Status count n is then snapshot n again. The probe's reader may match the world late or
    lose samples when it is starved (its queue is 100 deep, as every stream reader's). Up to
    each status the sensor has counted no more snapshots than were sent before that status went
    out; when it has counted more, the probe missed the difference, and they are put in the
    widest gap between the snapshots it did see since the previous status (at the start when it
    matched late).
    """
    adc, statuses = run['adc_snapshot'], run['position_sensor_status']
    fixed: list[float] = []
    backlog: list[int] = []  # per status: snapshots sent before it that it had not counted
    taken, count, last, missed = 0, 0, None, 0
    for t, f in statuses:
        n = f['sample_count']
        count = n if last is None else count + ((n - last) & 0xFFFF)
        last = n
        upto = bisect.bisect_right(adc, t)
        chunk = adc[taken:upto]
        gap = count - len(fixed) - len(chunk)
        if gap > 0:
            times = ([fixed[-1]] if fixed else [-math.inf]) + chunk
            widest = max(range(len(chunk) + 1), key=lambda k: times[k + 1] - times[k]
                         if k < len(chunk) else (-1.0 if fixed else -math.inf))
            chunk = chunk[:widest] + [math.nan] * gap + chunk[widest:]
            missed += gap
        backlog.append(max(0, -gap))
        fixed += chunk
        taken = upto
    fixed += adc[taken:]
    if missed:
        print(f'note: the probe missed {missed} of {len(fixed)} snapshots (placed as gaps)',
              file=sys.stderr)
    run['adc_snapshot'] = fixed
    run['backlog'] = backlog
    return run


def backlog_table(backlog: list[int]) -> str:
    """How far behind the world's 340 Hz the position sensor was when it sent each status."""
    s = sorted(backlog)
    behind = sum(1 for b in s if b > 0)
    return ('\n| position_sensor at its statuses | value |\n|---|---|\n'
            f'| statuses | {len(s)} |\n'
            f'| snapshots sent but not yet counted (in flight or queued), p50 / p99 / max | '
            f'{s[len(s) // 2]} / '
            f'{s[min(len(s) - 1, int(0.99 * len(s)))]} / {s[-1]} |\n'
            f'| statuses sent with at least one such snapshot | {behind} '
            f'({100 * behind / len(s):.2f} %) |')


def why(launch, lines: list[str]) -> str:
    """Say what a failed live run leaves to go on: dead nodes, reports, the graph's last lines."""
    tail = '\n  '.join(launch.lines[-25:])
    return (f'\nnodes exited: {launch.exits or "none"}\nreports: {lines[-5:]}\n'
            f'last graph output:\n  {tail}')


def live(time_factor: float, extra: dict[str, list[str]], tasks: int = 2,
         realtime: int = 0) -> dict[str, list]:
    """Run the first `tasks` tasks of the demonstration programme on a launched graph.

    Return every message's send time (wall s).
    """
    from agv_nodes.demo import comms_handshake
    from agv_nodes.harness import DEMO_PROGRAMME

    programme = DEMO_PROGRAMME[:tasks]
    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch

    out = Path(tempfile.mkdtemp(prefix='agv_latency_bench_'))
    launch = Launch(Options(time_factor=time_factor, bag=out / 'bag', quiet=True, extra=extra,
                            realtime=realtime))
    launch.join()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String, UInt8MultiArray

    from agv_nodes import qos

    c = codec()
    run: dict[str, list] = {name: [] for name in TOPICS.values()}
    rclpy.init()
    node = rclpy.create_node('latency_probe')
    for topic, name in TOPICS.items():
        def on_msg(raw: bytes, info: dict, name: str = name) -> None:
            sent = (info.get('source_timestamp') or 0) * 1e-9
            run[name].append(sent if name in ('adc_snapshot', 'traction_drive')
                             else (sent, uint8_array_data(raw)))
        # (msg, info) callbacks need the single-threaded executor in rclpy 7.1.6
        node.create_subscription(UInt8MultiArray, topic.lstrip('/'), on_msg,
                                 qos.reader_qos(c[name]), raw=True)
    lines: list[str] = []
    pub = node.create_publisher(String, 'comms/task', qos.EVENTS)
    node.create_subscription(String, 'comms/report', lambda m: lines.append(m.data), qos.EVENTS)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    launch.start()
    try:
        deadline = time.monotonic() + 120
        while not launch.moving.is_set() or pub.get_subscription_count() == 0:
            executor.spin_once(timeout_sec=0.1)
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError(f'the graph did not come up{why(launch, lines)}')
        comms_handshake(lambda: executor.spin_once(timeout_sec=0.05),
                        lambda text: pub.publish(String(data=text)), lines)
        for text in programme:
            pub.publish(String(data=text))
        deadline = time.monotonic() + 60 + 120 * len(programme)
        while sum(': completed' in x or ': FAILED' in x for x in lines) < len(programme):
            executor.spin_once(timeout_sec=0.1)
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError(f'the programme did not finish{why(launch, lines)}')
        for _ in range(20):  # the last statuses and drives in flight
            executor.spin_once(timeout_sec=0.01)
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
        launch.stop()
    for line in lines:
        if line.startswith('task '):
            print(f'  {line}', file=sys.stderr)
    for name in ('position_sensor_status', 'traction_link'):
        run[name] = [(t, c.decode(name, data, integrity=record_integrity(data)))
                     for t, data in run[name]]
    return align(run)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('bags', nargs='*', type=Path)
    ap.add_argument('--live', action='store_true', help='measure a running graph (wall time)')
    ap.add_argument('--time-factor', type=float, default=1.0)
    ap.add_argument('--tasks', type=int, default=2, help='live: the first N tasks of the '
                    'demonstration programme (2: the quick programme; 8: all of it)')
    ap.add_argument('-p', '--param', action='append', default=[],
                    help='NODE:NAME:=VALUE for one node, e.g. traction:link_reaction:=loop')
    ap.add_argument('--realtime', type=int, default=0, metavar='PRIORITY',
                    help="live: agv-launch's --realtime (the chain at SCHED_FIFO priority)")
    args = ap.parse_args()
    if args.live:
        extra: dict[str, list[str]] = {}
        for spec in args.param:
            node, _, arg = spec.partition(':')
            extra.setdefault(node, []).append(arg)
        run = live(args.time_factor, extra, args.tasks, args.realtime)
        rt = f' realtime {args.realtime}' if args.realtime else ''
        print(table(f'live graph, time_factor {args.time_factor:g}, {args.tasks} tasks{rt} '
                    f'{" ".join(args.param)} (wall time)', hops(run)))
        print(backlog_table(run['backlog']))
    for bag in args.bags:
        print(table(f'{bag} (sim time)', hops(read(bag))))
    return 0


if __name__ == '__main__':
    sys.exit(main())
