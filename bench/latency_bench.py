"""Sensor-to-traction latency from a recorded run (issue 8), hop by hop, in sim time.

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
node's clock moves in /clock steps (3 samples, 8.8 ms), which quantises hops 2 and 3.
Prints Markdown tables: n, p50, p99, max per hop, in ms of sim time.
"""

from __future__ import annotations

import argparse
import bisect
from pathlib import Path
import sys

from agv_nodes.records import codec
from agv_nodes.report import record_integrity, uint8_array_data

TOPICS = {'/hw/position_sensor/adc': 'adc_snapshot',
          '/position_sensor/status': 'position_sensor_status',
          '/traction/link': 'traction_link', '/hw/traction/drive': 'traction_drive'}


def read(bag: Path) -> dict[str, list]:
    """Sent times (s) of every ADC snapshot and traction_drive; (time, fields) of the statuses
    and links."""
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
        if 0 < count <= len(adc):
            out['adc_to_status'].append(t - adc[count - 1])
    link_times = [t for t, _f in links]
    for (t, f), (_t, count) in zip(statuses, processed, strict=True):
        if not f['recognised'] or not 0 < count <= len(adc):
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('bags', nargs='+', type=Path)
    args = ap.parse_args()
    for bag in args.bags:
        print(table(f'{bag} (sim time)', hops(read(bag))))
    return 0


if __name__ == '__main__':
    sys.exit(main())
