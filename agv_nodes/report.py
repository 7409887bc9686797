"""agv-report BAG: what happened in a recorded run, in numbers and pictures.

Decodes every 16-byte record of the bag (rosbags, the codec) and writes report.json (record counts,
stops, markers, faults, tasks), summary.md and PNG plots: speed against time with the marker events
(thesis fig 6.12), the path against the route, the stop errors (fig 7.15 style), records per
sub-system over time, and the faults.
"""

import argparse
from collections import Counter, defaultdict
import json
import math
from pathlib import Path
import sys
from typing import Any

import numpy as np

from agv_nodes.records import RecordError, codec
from agv_nodes.records.carrier import uint8_array_data

SUBSYSTEM_OF = {'navigation': 'navigation', 'position_sensor': 'position sensor',
                'traction': 'traction', 'route': 'route following', 'load': 'load handling',
                'comms': 'communications', 'hw': 'hardware', 'world': 'world'}
ROUTE_TOPIC = 'world/route'  # the layout's wires and tapes (agv_nodes.world.viz), latched
MARKER_ADD, MARKER_LINE_STRIP = 0, 4  # visualization_msgs/Marker's action and type constants


def _record_for(topic: str, by_topic: dict[str, Any]) -> Any:
    """Return the schema of a record topic, whatever namespace it was recorded under."""
    for name, schema in by_topic.items():
        if topic == '/' + name or topic.endswith('/' + name):
            return schema
    return None


def is_route_topic(topic: str) -> bool:
    """Whether a nav_msgs/Path topic is the world's route (world/route), in any namespace."""
    return topic == '/' + ROUTE_TOPIC or topic.endswith('/' + ROUTE_TOPIC)


def path_points(msg: Any) -> list[tuple[float, float]]:
    """(x, y) of each pose of a nav_msgs/Path."""
    return [(p.pose.position.x, p.pose.position.y) for p in msg.poses]


def circle_through(points: list[tuple[float, float]]) -> tuple[float, float, float] | None:
    """(centre x, centre y, radius) of the least-squares circle through `points` (Kasa).

    Exact for points on a circle, however spaced (a closed line strip repeats its first point:
    no matter); None for fewer than three points or points in a line.
    """
    if len(points) < 3:
        return None
    xy = np.asarray(points, dtype=float)
    a = np.column_stack([2.0 * xy, np.ones(len(xy))])
    (cx, cy, c), _res, rank, _sv = np.linalg.lstsq(a, (xy * xy).sum(axis=1), rcond=None)
    if rank < 3 or not c + cx * cx + cy * cy > 0.0:
        return None
    return float(cx), float(cy), math.sqrt(c + cx * cx + cy * cy)


def read_bag(bag: Path) -> dict[str, Any]:
    """Decode a bag: records per topic (time, fields), poses, route, paths, strings, diagnostics.

    data['route']: the layout's wires and tapes, (x, y) of the first message on world/route.
    data['paths']: every other nav_msgs/Path topic, {topic: [(t, [(x, y), ...]), ...]} (such as
    route/identified_track, in the odometry frame). data['markers']: each visualization_msgs/
    Marker topic's line strips drawn as circles, {topic: [(t, centre x, centre y, radius)]}
    (route/osculating_circle; a DELETE, a straight track, adds nothing). data['pose']: (t, x,
    y, heading) of each geometry_msgs/PoseStamped (the world's truck pose, world/pose).
    """
    from rosbags.highlevel import AnyReader

    c = codec()
    by_topic = {s.topic: s for s in c}
    data: dict[str, Any] = {'records': defaultdict(list), 'pose': [], 'route': [],
                            'paths': defaultdict(list), 'markers': defaultdict(list),
                            'strings': defaultdict(list), 'diagnostics': [], 'counts': Counter(),
                            'types': {}, 'rejected': Counter(), 'start': None, 'end': None}
    route_read = False
    paths = [bag] + sorted(bag.parent.glob(f'{bag.name}_[0-9]*'))
    schemas: dict[str, Any] = {}  # topic -> record schema (None: not a record topic)
    msg: Any  # rosbags deserializes to `object`: the class is the connection's msgtype's
    with AnyReader(paths) as reader:
        for conn, stamp, raw in reader.messages():
            t = stamp * 1e-9
            data['start'] = t if data['start'] is None else min(data['start'], t)
            data['end'] = t if data['end'] is None else max(data['end'], t)
            data['counts'][conn.topic] += 1
            data['types'][conn.topic] = conn.msgtype
            if conn.msgtype == 'std_msgs/msg/UInt8MultiArray':
                if conn.topic not in schemas:
                    schemas[conn.topic] = _record_for(conn.topic, by_topic)
                schema = schemas[conn.topic]
                if schema is None:
                    continue
                record = uint8_array_data(raw)
                if record is None:
                    msg = reader.deserialize(raw, conn.msgtype)
                    record = bytes(msg.data)
                try:
                    fields = schema.decode(record, integrity='none' if not
                                           schema.protected else record_integrity(record))
                except RecordError:
                    data['rejected'][schema.name] += 1
                    continue
                data['records'][schema.name].append((t, fields))
            elif conn.msgtype == 'geometry_msgs/msg/PoseStamped':
                msg = reader.deserialize(raw, conn.msgtype)
                q = msg.pose.orientation
                data['pose'].append((t, msg.pose.position.x, msg.pose.position.y,
                                     2 * math.atan2(q.z, q.w)))
            elif conn.msgtype == 'nav_msgs/msg/Path':
                if not is_route_topic(conn.topic):
                    msg = reader.deserialize(raw, conn.msgtype)
                    data['paths'][conn.topic].append((t, path_points(msg)))
                elif not route_read:  # latched: drawn once, maybe recorded again
                    data['route'] = path_points(reader.deserialize(raw, conn.msgtype))
                    route_read = True
            elif conn.msgtype == 'visualization_msgs/msg/Marker':
                msg = reader.deserialize(raw, conn.msgtype)
                if msg.action == MARKER_ADD and msg.type == MARKER_LINE_STRIP and (
                        circle := circle_through([(q.x, q.y) for q in msg.points])):
                    data['markers'][conn.topic].append((t, *circle))
            elif conn.msgtype == 'std_msgs/msg/String':
                msg = reader.deserialize(raw, conn.msgtype)
                data['strings'][conn.topic.rsplit('/', 1)[-1]].append((t, msg.data))
            elif conn.msgtype == 'diagnostic_msgs/msg/DiagnosticArray':
                msg = reader.deserialize(raw, conn.msgtype)
                for st in msg.status:
                    level = st.level if isinstance(st.level, int) else int.from_bytes(
                        bytes(st.level), 'little')
                    if level >= 2:
                        data['diagnostics'].append((t, st.name, st.message))
    return data


def record_integrity(raw: bytes) -> str:
    """Protected records in a bag: e2e when bytes 15-16 are set, else a plain (none) peer."""
    return 'e2e' if raw[14] or raw[15] else 'none'


def final_stops(events: list[dict[str, Any]], merge_s: float = 5.0) -> list[dict[str, Any]]:
    """One entry per stop from the world's `stopped` events: where the truck finally rested.

    An overshooting controlled stop (thesis 8.5) rests, backs up and rests again: rests at one
    marker under `merge_s` apart, no load moved between, are one stop (`rests`, `speed_mm_s`).
    """
    stops: list[dict[str, Any]] = []
    merge = False  # a rest may join the previous one
    for e in events:
        if e['event'] == 'load_moved':
            merge = False
        if e['event'] != 'stopped':
            continue
        stop = {'time': e['time'], 'marker': _marker_name(e), 'error_mm': e['error'],
                'speed_mm_s': e['speed'], 'rests': 1}
        last = stops[-1] if stops else None
        if merge and last and last['marker'] == stop['marker'] and \
                stop['time'] - last['time'] < merge_s:
            stops[-1] = {**stop, 'speed_mm_s': last['speed_mm_s'], 'rests': last['rests'] + 1}
        else:
            stops.append(stop)
        merge = True
    return stops


def analyse(data: dict[str, Any]) -> dict[str, Any]:
    """Work out the numbers of the report."""
    events = [f | {'time': t} for t, f in data['records'].get('world_event', [])]
    stops = final_stops(events)
    markers = [{'time': e['time'], 'marker': _marker_name(e), 'speed_mm_s': e['speed'],
                'range_error_mm': e['error']} for e in events if e['event'] == 'marker_passed']
    loads = [{'time': e['time'], 'marker': _marker_name(e)} for e in events
             if e['event'] == 'load_moved']
    reports = data['strings'].get('report', [])
    tasks = [{'time': t, 'text': line} for t, line in reports
             if ': completed' in line or ': FAILED' in line or ': rejected' in line]
    faults = [f'{t:.1f} s: {line}' for t, line in reports if 'FAILED' in line]
    for t, f in data['records'].get('traction_status', []):
        if f['tripped'] and f['trip_cause'] not in ('startup', 'none'):
            faults.append(f'{t:.1f} s: traction tripped ({f["trip_cause"]})')
            break
    diag = sorted({(name, msg) for _t, name, msg in data['diagnostics']})
    faults += [f'diagnostics ERROR {name}: {msg}' for name, msg in diag[:20]]
    errors = [s['error_mm'] for s in stops if s['marker'] != '-']
    mean = sum(errors) / len(errors) if errors else 0.0
    spread = (max(errors) - min(errors)) / 2 if errors else 0.0
    return {
        'duration_s': (data['end'] or 0) - (data['start'] or 0),
        'messages': sum(data['counts'].values()),
        'topics': {t: {'type': data['types'][t], 'count': n}
                   for t, n in sorted(data['counts'].items())},
        'records_decoded': {k: len(v) for k, v in sorted(data['records'].items())},
        'records_rejected': dict(data['rejected']),
        'stops': stops, 'stop_error_mean_mm': mean, 'stop_error_half_range_mm': spread,
        'markers': markers, 'loads': loads, 'tasks': tasks, 'faults': faults,
    }


def _marker_name(e: dict[str, Any]) -> str:
    if e['marker_kind'] == 'location':
        return f'L{e["identity"]}'
    if e['marker_kind'] == 'stop':
        station = f'W{e["station"]}' if e['station'] != 0xFF else 'S'
        return f'{station}.{e["identity"]}'
    return '-'


def plots(data: dict[str, Any], result: dict[str, Any], out: Path) -> list[str]:
    """Write the PNG plots; return their file names."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written: list[str] = []

    def save(fig, name: str) -> None:
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)
        plt.close(fig)
        written.append(name)

    t0 = data['start'] or 0.0
    odo = data['records'].get('wheel_odometry', [])
    fig, ax = plt.subplots(figsize=(12, 4))
    if odo:
        ax.plot([t - t0 for t, _f in odo],
                [(f['left_speed'] + f['right_speed']) / 2000 for _t, f in odo], lw=0.8,
                label='speed (wheel odometry)')
    for m in result['markers']:
        ax.axvline(m['time'] - t0, color='tab:green' if m['marker'].startswith('L')
                   else 'tab:red', lw=0.5, alpha=0.6)
        ax.text(m['time'] - t0, 1.05, m['marker'], fontsize=6, rotation=90, va='bottom')
    for s in result['stops']:
        ax.plot(s['time'] - t0, 0, 'kv', ms=5)
    ax.set(xlabel='time (s)', ylabel='speed (m/s)', ylim=(-0.05, 1.2), title='Speed with marker '
           'passages (green: location, red: stop) and stops (thesis fig 6.12)')
    ax.legend(loc='upper right')
    save(fig, 'speed.png')

    fig, ax = plt.subplots(figsize=(8, 7))
    if data['route']:
        ax.plot(*zip(*data['route'], strict=True), '.', ms=1, color='0.6', label='wires')
    if data['pose']:
        ax.plot([p[1] for p in data['pose']], [p[2] for p in data['pose']], lw=0.7,
                color='tab:blue', label='truck (rear axle)')
    ax.set(aspect='equal', title='Path against the route (plan view)', xlabel='x (m)',
           ylabel='y (m)')
    ax.legend(loc='best')
    save(fig, 'path.png')

    fig, ax = plt.subplots(figsize=(8, 4))
    if stops := result['stops']:
        ax.bar(range(1, len(stops) + 1), [s['error_mm'] for s in stops], color='tab:orange')
        ax.set_xticks(range(1, len(stops) + 1), [s['marker'] for s in stops], rotation=45,
                      fontsize=7)
    ax.axhline(0, color='k', lw=0.8)
    ax.axhspan(-40, 40, color='tab:green', alpha=0.1, label='thesis +-4 cm')
    ax.set(ylabel='stop error (mm, + = past the marker centre)',
           title='Stop errors per stop (fig 7.15 style)')
    ax.legend(loc='best')
    save(fig, 'stops.png')

    fig, ax = plt.subplots(figsize=(12, 4))
    names = sorted(data['records'])
    for i, name in enumerate(names):
        times = [t - t0 for t, _f in data['records'][name]][::5]
        ax.plot(times, [i] * len(times), '|', ms=4)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.set(xlabel='time (s)', title='Records per sub-system over time (every 5th shown)')
    save(fig, 'records.png')

    fig, ax = plt.subplots(figsize=(10, 3))
    ax.axis('off')
    ax.text(0, 1, '\n'.join((result['faults'] or ['no faults'])[:25]), va='top',
            family='monospace', fontsize=8)
    ax.set_title('Faults')
    save(fig, 'faults.png')
    return written


def summary_markdown(result: dict[str, Any], pictures: list[str]) -> str:
    """summary.md."""
    lines = ['# Run summary', '',
             f'- duration {result["duration_s"]:.1f} s (sim time), {result["messages"]} '
             f'messages on {len(result["topics"])} topics',
             f'- stops: {len(result["stops"])}, mean error {result["stop_error_mean_mm"]:+.1f} '
             f'mm, +-{result["stop_error_half_range_mm"]:.1f} mm about the mean',
             f'- loads moved: {len(result["loads"])}; marker passages: {len(result["markers"])}',
             f'- records rejected while decoding the bag: '
             f'{sum(result["records_rejected"].values())}', '',
             '## Tasks', '']
    lines += [f'- {t["time"]:.1f} s: {t["text"]}' for t in result['tasks']] or ['- none']
    lines += ['', '## Stops', '', '| # | marker | error (mm) | speed before (mm/s) |',
              '|---|---|---|---|']
    lines += [f'| {i} | {s["marker"]} | {s["error_mm"]:+d} | {s["speed_mm_s"]} |'
              for i, s in enumerate(result['stops'], 1)]
    lines += ['', '## Faults', ''] + ([f'- {f}' for f in result['faults']] or ['- none'])
    lines += ['', '## Plots', ''] + [f'![{p}]({p})' for p in pictures]
    return '\n'.join(lines) + '\n'


def make_report(bag: Path, out: Path) -> dict[str, Any]:
    """Write report.json, summary.md and the plots for `bag` into `out`."""
    out.mkdir(parents=True, exist_ok=True)
    data = read_bag(Path(bag))
    result = analyse(data)
    pictures = plots(data, result, out)
    (out / 'report.json').write_text(json.dumps(result, indent=2))
    (out / 'summary.md').write_text(summary_markdown(result, pictures))
    return result


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-report."""
    ap = argparse.ArgumentParser(prog='agv-report', description=__doc__.splitlines()[0])
    ap.add_argument('bag', type=Path)
    ap.add_argument('--out', type=Path, help='output directory (default: <bag>_report); with '
                    '--channels the CSV file (default: <bag>_channels.csv)')
    ap.add_argument('--channels', action='store_true',
                    help="write the camera truck's 12 software channels, 50 ms apart, as CSV "
                    '(agv_nodes.channels) instead')
    ap.add_argument('--layout', help='a camera-truck run on this tape layout (name or file): '
                    'write the camera report (agv_nodes.camera_report) instead')
    args = ap.parse_args(argv)
    if not (args.bag / 'metadata.yaml').is_file():
        print(f'agv-report: {args.bag} is not a rosbag2 bag (no metadata.yaml)', file=sys.stderr)
        return 2
    if args.channels:
        from agv_nodes.channels import export

        try:
            path, rows = export(args.bag, args.out)
        except ValueError as exc:
            print(f'agv-report: {exc}', file=sys.stderr)
            return 2
        print(f'{rows} samples of the 12 software channels; wrote {path}')
        return 0
    out = args.out or args.bag.with_name(args.bag.name + '_report')
    if args.layout:
        from agv_nodes.camera_report import make_camera_report  # it imports this module

        result = make_camera_report(args.bag, out, args.layout)
        print(f'{len(result["legs"])} legs, {len(result["stops"])} stops; wrote {out}')
        return 0
    result = make_report(args.bag, out)
    print(f'{len(result["stops"])} stops, {len(result["faults"])} faults; wrote {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
