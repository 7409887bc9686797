"""agv-report --layout NAME: a CONCIC-II camera-truck run (Rajagopalan 1991) in numbers, pictures.

Reads the bag with `agv_nodes.report.read_bag` and writes into the output directory report.json,
summary.md and two plots: camera_path.png, the ground-truth path over the tape layout with both
camera windows and the road signs (and, from a feed_forward run, route/identified_track placed in
the world at the first pose), and camera_timeline.png, the lateral error and the speed
against time with the sign, junction and stop events. The events (signs met, junction turns and
waits, stops, task results) and the numbers per leg (distance, duration, RMS and max |lateral
error| while the tape steers the truck) go into both text files, and the identified track's
distance from the tape.
"""

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from agv_nodes.report import read_bag
from agv_nodes.track_report import identified_track_messages, identified_track_numbers
from agv_nodes.world.layout import Layout, layout_path, load_layout
from agv_nodes.world.settings import WorldParams

# States in which the tape steers the truck (through a sign's wide patch too): only their
# lateral error measures the following; turning, waiting and stopped phases would swamp it.
STEERED = ('following', 'sign')
# States in which route following switched the motors off: the cause of the stop that follows.
HALTS = ('lost', 'no_track', 'no_branch', 'drive_fault', 'obstacle')
JUNCTION_PHASES = ('turning', 'waiting')
TASK_ENDS = (': completed', ': FAILED', ': rejected')
FAILURE_WINDOW_S = 2.0  # a FAILED report this close to a stop is that stop's failure
WINDOW_INSTANTS = 12  # camera windows drawn at this many regular instants along the run
# Pose differences span this much: the bag stamps a 20 ms pose step by when the recorder saw the
# clock, 18-27 ms apart, and a short span would turn that jitter into speed ripple.
SPEED_WINDOW_S = 0.5


class Track:
    """The ground-truth pose of the axle centre (world/pose) as arrays, looked up by time."""

    def __init__(self, pose: list[tuple[float, float, float, float]]) -> None:
        self.t, self.x, self.y, self.h = np.array(pose, dtype=float).reshape(-1, 4).T

    def at(self, t: float) -> tuple[float, float, float]:
        """(x, y, heading) of the last pose at or before `t` (the first pose before it)."""
        if not len(self.t):
            return (math.nan, math.nan, math.nan)
        i = max(int(np.searchsorted(self.t, t, side='right')) - 1, 0)
        return float(self.x[i]), float(self.y[i]), float(self.h[i])

    def distance(self, start: float, end: float) -> float:
        """M the axle centre travelled between `start` and `end` (forward and reverse alike)."""
        inside = (self.t >= start) & (self.t <= end)
        return float(np.hypot(np.diff(self.x[inside]), np.diff(self.y[inside])).sum())

    def speed(self) -> np.ndarray:
        """Signed speed (m/s, - = reversing) at each pose, over SPEED_WINDOW_S centred on it."""
        if not len(self.t):
            return np.zeros(0)
        i = np.searchsorted(self.t, self.t - SPEED_WINDOW_S / 2, side='left')
        j = np.searchsorted(self.t, self.t + SPEED_WINDOW_S / 2, side='right') - 1
        dt = self.t[j] - self.t[i]
        along = (self.x[j] - self.x[i]) * np.cos(self.h) + (self.y[j] - self.y[i]) * np.sin(self.h)
        return np.divide(along, dt, out=np.zeros_like(along), where=dt > 0)


def runs(status: list[tuple[float, dict[str, Any]]]) -> list[dict[str, Any]]:
    """Consecutive route_status records in one state: state, start, end (next run), records."""
    out: list[dict[str, Any]] = []
    for t, f in status:
        if out and out[-1]['state'] == f['state']:
            out[-1]['records'].append(f)
            continue
        if out:
            out[-1]['end'] = t
        out.append({'state': f['state'], 'start': t, 'end': t, 'records': [f]})
    if out:
        out[-1]['end'] = status[-1][0]
    return out


def leg_spans(data: dict[str, Any]) -> list[dict[str, Any]]:
    """Each leg: while route_command names it in a driving mode (else route_status's echo)."""
    samples = [(t, f['leg'], f['mode'] != 'idle', f['direction'])
               for t, f in data['records'].get('route_command', [])]
    if not any(active for _t, _leg, active, _d in samples):
        samples = [(t, f['leg'], f['state'] != 'idle', '-')
                   for t, f in data['records'].get('route_status', [])]
    spans: list[dict[str, Any]] = []
    current: dict[str, Any] | None = None
    for t, leg, active, direction in samples:
        if current and (not active or leg != current['leg']):
            spans.append(current | {'end': t})
            current = None
        if active and current is None:
            current = {'leg': leg, 'direction': direction, 'start': t}
    if current:
        spans.append(current | {'end': data['end']})
    return spans


def leg_numbers(data: dict[str, Any], track: Track) -> list[dict[str, Any]]:
    """Distance, duration and lateral error of each leg (error only while the tape steers)."""
    status = data['records'].get('route_status', [])
    speed = np.abs(track.speed())
    legs = []
    for span in leg_spans(data):
        inside = [f for t, f in status if span['start'] <= t <= span['end']]
        errors = [abs(f['lateral_error']) for f in inside if f['state'] in STEERED]
        moving = speed[(track.t >= span['start']) & (track.t <= span['end'])]
        legs.append(span | {
            'duration_s': span['end'] - span['start'],
            'distance_m': track.distance(span['start'], span['end']),
            'peak_speed_m_s': float(moving.max()) if len(moving) else None,
            'odometry_distance_m': max((f['distance'] for f in inside), default=0) / 100,
            'junctions': max((f['junctions'] for f in inside), default=0),
            'lateral_samples': len(errors),
            'lateral_rms_mm': math.sqrt(sum(e * e for e in errors) / len(errors))
            if errors else None,
            'lateral_max_mm': max(errors, default=None)})
    return legs


def where(layout: Layout, track: Track, t: float) -> dict[str, Any]:
    """Pose at `t` and the tape under the axle centre (id, m along it, lateral m)."""
    x, y, h = track.at(t)
    if math.isnan(x):
        return {'x': None, 'y': None, 'heading_deg': None, 'tape': None, 's': None,
                'lateral_m': None}

    # The distance to the nearest point, not project()'s lateral: that is square to the
    # nearest segment even beyond a tape's end, so every tape in line would tie at 0.
    def off(pid: str) -> float:
        px, py, _h = layout.paths[pid].pose_at(layout.paths[pid].project(x, y)[0])
        return math.hypot(x - px, y - py)

    tape = min(layout.paths, key=off)
    s, lateral, _h = layout.paths[tape].project(x, y)
    return {'x': round(x, 3), 'y': round(y, 3), 'heading_deg': round(math.degrees(h), 1),
            'tape': tape, 's': round(s, 3), 'lateral_m': round(lateral, 3)}


def rest_times(data: dict[str, Any], track: Track) -> list[float]:
    """When the truck came to rest: the world's `stopped` events, else from the pose's speed."""
    events = [t for t, f in data['records'].get('world_event', []) if f['event'] == 'stopped']
    if events or not len(track.t):
        return events
    rests, moving = [], False
    for t, v in zip(track.t, np.abs(track.speed()), strict=True):
        if v > 0.01:
            moving = True
        elif moving and v < 1e-3:
            moving = False
            rests.append(float(t))
    return rests


def leg_at(legs: list[dict[str, Any]], t: float) -> int | None:
    """Return the leg running at `t` (the last one begun by then), None before the first."""
    begun = [g['leg'] for g in legs if g['start'] <= t]
    return begun[-1] if begun else None


def events(data: dict[str, Any], layout: Layout, track: Track,
           legs: list[dict[str, Any]]) -> dict[str, list]:
    """Signs met, junction turns and waits, stops and task results."""
    status = data['records'].get('route_status', [])
    commands = data['records'].get('route_command', [])
    phases = runs(status)
    signs, junction = [], []
    for k, run in enumerate(phases):
        if run['state'] == 'sign':
            # The straight flag is set as the track narrows again: read the run after it too.
            seen = run['records'] + (phases[k + 1]['records'] if k + 1 < len(phases) else [])
            signs.append({'time': run['start'], 'junctions': max(f['junctions'] for f in seen),
                          'leg': leg_at(legs, run['start']),
                          **{flag: max(f[f'sign_{flag}'] for f in seen)
                             for flag in ('left', 'right', 'straight')},
                          'where': where(layout, track, run['start'])})
        elif run['state'] in JUNCTION_PHASES:
            # The decision offered for this junction: the executive moves on to the next
            # junction's as soon as route following counts this one.
            n = max(f['junctions'] for f in run['records'])
            mine = [f for t, f in commands if t <= run['end']
                    and f.get('junction_number', 0) in (0, n)]
            junction.append({'kind': run['state'], 'time': run['start'],
                             'leg': leg_at(legs, run['start']),
                             'duration_s': run['end'] - run['start'],
                             'junctions': n,
                             'decision': mine[-1]['junction'] if mine else None,
                             'where': where(layout, track, run['start'])})
    reports = data['strings'].get('report', [])
    tasks = [{'time': t, 'text': line} for t, line in reports
             if any(end in line for end in TASK_ENDS)]
    stops, since = [], -math.inf
    for t in rest_times(data, track):
        states = [f['state'] for s, f in status if since < s <= t]
        halts = [s for s in states if s in HALTS]
        cause = halts[-1] if halts else (states[-1] if states else 'unknown')
        if cause == 'idle':
            cause = 'idle (leg end)'
        failures = [line for s, line in reports if 'FAILED' in line
                    and abs(s - t) <= FAILURE_WINDOW_S]
        stops.append({'time': t, 'leg': leg_at(legs, t), 'cause': cause,
                      'failure': failures[0] if failures else None,
                      'where': where(layout, track, t)})
        since = t
    return {'signs': signs, 'junction_phases': junction, 'stops': stops, 'tasks': tasks}


def analyse_camera(data: dict[str, Any], layout: Layout) -> dict[str, Any]:
    """Work out the numbers and events of the camera report."""
    track = Track(data['pose'])
    camera = WorldParams()
    steered = [abs(f['lateral_error']) for _t, f in data['records'].get('route_status', [])
               if f['state'] in STEERED]
    legs = leg_numbers(data, track)
    result = {
        'layout': layout.name, 'start': data['start'], 'end': data['end'],
        'duration_s': (data['end'] or 0) - (data['start'] or 0),
        'camera': {'distance_m': camera.concic2.camera_distance,
                   'depth_m': camera.camera.depth, 'width_m': camera.camera.width},
        'layout_signs': [{'type': s['type'], 'tape': s['path'], 'at_m': s['at']}
                         for s in layout.signs],
        'legs': legs,
        'lateral_rms_mm': math.sqrt(sum(e * e for e in steered) / len(steered))
        if steered else None,
        'lateral_max_mm': max(steered, default=None),
        **events(data, layout, track, legs)}
    if identified := identified_track_numbers(data, layout):
        result['identified_track'] = identified
    return result


def window_corners(x: float, y: float, h: float, ahead: float, depth: float,
                   width: float) -> np.ndarray:
    """Corners of a camera window `ahead` m along the heading (- = behind the axle)."""
    c = np.array([x + ahead * math.cos(h), y + ahead * math.sin(h)])
    along = depth / 2 * np.array([math.cos(h), math.sin(h)])
    across = width / 2 * np.array([-math.sin(h), math.cos(h)])
    return np.array([c + along + across, c + along - across, c - along - across,
                     c - along + across])


def plots(data: dict[str, Any], result: dict[str, Any], layout: Layout, out: Path) -> list[str]:
    """Write camera_path.png and camera_timeline.png; return their file names."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon
    import matplotlib.pyplot as plt

    track, cam = Track(data['pose']), result['camera']
    fig, ax = plt.subplots(figsize=(9, 8))
    for pid, p in layout.paths.items():
        ax.plot(p.points[:, 0], p.points[:, 1], color='0.25' if 'patch' not in pid else '0.5',
                lw=4 if 'patch' not in pid else 7, alpha=0.5, solid_capstyle='butt')
    for s in layout.signs:
        x, y, _h = layout.paths[s['path']].pose_at(s['at'])
        ax.plot(x, y, 'D', color='tab:orange', ms=8)
        ax.annotate(s['type'], (x, y), xytext=(6, 6), textcoords='offset points',
                    color='tab:orange', weight='bold')
    ax.plot(track.x, track.y, lw=1, color='tab:blue')
    identified = identified_track_messages(data)
    for _t, points in identified:
        ax.plot(points[:, 0], points[:, 1], '.-', lw=0.6, ms=1.5, color='tab:green', alpha=0.8,
                zorder=3)
    # Regular instants while a leg runs: the truck at rest would pile the windows on one spot.
    legs = result['legs'] or ([{'start': track.t[0], 'end': track.t[-1]}] if len(track.t) else [])
    instants = list(np.linspace(legs[0]['start'], legs[-1]['end'], WINDOW_INSTANTS)) if legs \
        else []
    marked = [e['time'] for e in result['signs'] + result['junction_phases']]
    for t in instants + marked:
        x, y, h = track.at(t)
        alpha = 0.9 if t in marked else 0.4
        for ahead, colour in ((cam['distance_m'], 'tab:red'), (-cam['distance_m'], 'tab:purple')):
            ax.add_patch(Polygon(window_corners(x, y, h, ahead, cam['depth_m'], cam['width_m']),
                                 closed=True, fill=False, color=colour, lw=1, alpha=alpha))
        ax.plot(x, y, '.', color='tab:blue', ms=4)
    ax.legend(handles=[Line2D([], [], color='0.25', lw=4, alpha=0.5, label='tape'),
                       Line2D([], [], color='tab:blue', label='axle centre (world/pose)'),
                       Line2D([], [], color='tab:red', label='front window'),
                       Line2D([], [], color='tab:purple', label='rear window'),
                       Line2D([], [], color='tab:orange', marker='D', ls='',
                              label='road sign')]
              + ([Line2D([], [], color='tab:green', marker='.', lw=0.6, ms=3,
                         label='identified track (odom, placed at the start pose)')]
                 if identified else []), loc='best', fontsize=8)
    ax.set(aspect='equal', xlabel='x (m)', ylabel='y (m)',
           title=f'Path on {layout.name}: camera windows at regular instants and at junctions')
    written = [_save(plt, fig, out / 'camera_path.png')]

    t0 = data['start'] or 0.0
    fig, (lat, vel) = plt.subplots(2, 1, figsize=(12, 6), sharex=True)
    status = data['records'].get('route_status', [])
    lat.plot([t - t0 for t, _f in status], [f['lateral_error'] for _t, f in status], '.',
             ms=2, color='tab:blue')
    lat.set(ylabel='lateral error (mm)', title='Lateral error and speed (green: sign, shaded: '
            'turning / waiting, red: stop)')
    if len(track.t):
        vel.plot(track.t - t0, track.speed(), lw=0.8, label='pose')
    odo = data['records'].get('wheel_odometry', [])
    vel.plot([t - t0 for t, _f in odo], [(f['left_speed'] + f['right_speed']) / 2000
                                         for _t, f in odo], lw=0.5, label='wheel odometry')
    vel.set(xlabel='time (s)', ylabel='speed (m/s)')
    vel.legend(loc='upper right', fontsize=8)
    for ax in (lat, vel):
        for s in result['signs']:
            ax.axvline(s['time'] - t0, color='tab:green', lw=0.8)
        for j in result['junction_phases']:
            ax.axvspan(j['time'] - t0, j['time'] + j['duration_s'] - t0, color='tab:orange',
                       alpha=0.2)
        for s in result['stops']:
            ax.axvline(s['time'] - t0, color='tab:red', lw=0.8, ls='--')
    written.append(_save(plt, fig, out / 'camera_timeline.png'))
    return written


def _save(plt: Any, fig: Any, file: Path) -> str:
    fig.tight_layout()
    fig.savefig(file, dpi=110)
    plt.close(fig)
    return file.name


def _at(w: dict[str, Any]) -> str:
    return f'{w["tape"]} {w["s"]:.2f} m' if w['tape'] else '-'


def _flags(sign: dict[str, Any]) -> str:
    flags = [f for f in ('left', 'right', 'straight') if sign[f]]
    return 'flags ' + ' '.join(flags) if flags else 'no flags'


def _num(value: float | None, fmt: str = '.1f') -> str:
    return '-' if value is None else format(value, fmt)


def summary_markdown(result: dict[str, Any], pictures: list[str]) -> str:
    """summary.md: the legs, then the events tables, then the plots."""
    lines = [f'# Camera run summary ({result["layout"]})', '',
             f'- duration {result["duration_s"]:.1f} s (sim time); lateral error while the '
             f'tape steers: RMS {_num(result["lateral_rms_mm"])} mm, max '
             f'{_num(result["lateral_max_mm"], "")} mm']
    if track := result.get('identified_track'):
        lines.append(
            f'- identified track (route/identified_track): {track["messages"]} messages, '
            f'{track["points"]} points, from the nearest tape centreline mean '
            f'{_num(track["mean_mm"])} mm, max {_num(track["max_mm"])} mm. Each message is '
            'placed in the world by the first truck pose, where its odom frame starts: these '
            "are the fit's error and the wheel odometry's drift since the start together.")
    lines += ['', '## Legs', '',
              '| leg | direction | start (s) | duration (s) | distance (m) | odometry (m) | '
              'junctions | RMS lateral (mm) | max lateral (mm) |', '|---' * 9 + '|']
    lines += [f'| {g["leg"]} | {g["direction"]} | {g["start"]:.1f} | {g["duration_s"]:.1f} | '
              f'{g["distance_m"]:.2f} | {g["odometry_distance_m"]:.2f} | {g["junctions"]} | '
              f'{_num(g["lateral_rms_mm"])} | {_num(g["lateral_max_mm"], "")} |'
              for g in result['legs']]
    lines += ['', '## Events', '', '| time (s) | event | junctions | detail | where |',
              '|---|---|---|---|---|']
    rows = [(s['time'], 'sign', s['junctions'], _flags(s), _at(s['where']))
            for s in result['signs']]
    rows += [(j['time'], j['kind'], j['junctions'], f'{j["decision"] or "-"}, '
              f'{j["duration_s"]:.1f} s', _at(j['where'])) for j in result['junction_phases']]
    rows += [(s['time'], 'stop', '', s['cause'] + (f'; {s["failure"]}' if s['failure'] else ''),
              _at(s['where'])) for s in result['stops']]
    rows += [(t['time'], 'task', '', t['text'], '') for t in result['tasks']]
    lines += [f'| {t:.1f} | {kind} | {n} | {detail} | {at} |' for t, kind, n, detail, at in
              sorted(rows, key=lambda r: r[0])] or ['| - | none | | | |']
    lines += ['', '## Plots', ''] + [f'![{p}]({p})' for p in pictures]
    return '\n'.join(lines) + '\n'


def make_camera_report(bag: Path, out: Path, layout: str) -> dict[str, Any]:
    """Write report.json, summary.md and the plots of camera-truck `bag` on `layout` into `out`."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = read_bag(Path(bag))
    floor = load_layout(layout_path(layout))
    result = analyse_camera(data, floor)
    result['plots'] = plots(data, result, floor, out)
    (out / 'report.json').write_text(json.dumps(result, indent=2))
    (out / 'summary.md').write_text(summary_markdown(result, result['plots']))
    return result
