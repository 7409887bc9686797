"""Camera route following's CPU, and how well `lead` and `both` hold the tape, both ways.

Run: .venv/bin/python bench/route_cpu_bench.py [--seconds S] [--out FILE]

Lock step on tape_1991 (the R = 2.95 m circle with three road signs): the world core renders
both cameras at 20 frames/s, the route-following core steers the CONCIC-II with its 100 Hz
loop, and a scripted executive drives a forward leg, or a short forward leg, a motor-off stop
and a reverse leg. time.process_time is read around the core's own calls only (frames,
records, loop), so the world's rendering does not count. The same runs give each window's
lateral offset from the tape (ground truth, every 50 ms once settled): the numbers that chose
the default of `cameras`. A last table times the image passes (Rajagopalan 1991, Tables
4.1-4.2) a row at a time, as the thesis lays them out, and for the whole window at once.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

import numpy as np

from agv_nodes.harness import CameraLegScript, Harness
from agv_nodes.route_following.camera_guidance import ImageAnalyser, runs_of
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, layout_path, load_layout
from agv_nodes.world.settings import WorldParams

L_C = 0.64  # m, the camera windows from the axle
SETTLE = {'forward': 8.0, 'reverse': 5.0}  # s into the leg before offsets are taken
SIGN_ZONE = 0.45  # m: offsets within this of a sign's crossing are counted apart


class TimedRoute(RouteCore):
    """RouteCore with the CPU time of each of its calls added up, s."""

    def __init__(self, params: RouteParams) -> None:
        super().__init__(params)
        self.cpu = {'frames': 0.0, 'records': 0.0, 'loop': 0.0}

    def on_frame(self, frame, now, camera='front'):  # noqa: D102
        t = time.process_time()
        out = super().on_frame(frame, now, camera)
        self.cpu['frames'] += time.process_time() - t
        return out

    def on_record(self, record, fields, now):  # noqa: D102
        t = time.process_time()
        out = super().on_record(record, fields, now)
        self.cpu['records'] += time.process_time() - t
        return out

    def tick(self, now):  # noqa: D102
        t = time.process_time()
        out = super().tick(now)
        self.cpu['loop'] += time.process_time() - t
        return out


def windows(world: WorldCore) -> tuple[tuple[float, float], tuple[float, float]]:
    """Return the (front, rear) window centres, m."""
    s = world.vehicle.state
    c, n = math.cos(s.heading), math.sin(s.heading)
    return (s.x + L_C * c, s.y + L_C * n), (s.x - L_C * c, s.y - L_C * n)


def near_sign(lay: Layout, point: tuple[float, float]) -> bool:
    """Return whether `point` is within SIGN_ZONE of a sign's crossing."""
    return any(math.dist(point, lay.paths[sg['path']].pose_at(sg['at'])[:2]) < SIGN_ZONE
               for sg in lay.signs)


def run(cameras: str, direction: str, seconds: float) -> dict[str, float]:
    """Drive one leg for `seconds`; return CPU ms per simulated second and offsets, mm."""
    lay = load_layout(layout_path('tape_1991'))
    world = WorldCore(lay, WorldParams(seed=2, rear_camera=True))
    script, route = CameraLegScript(), TimedRoute(RouteParams(vehicle='concic2', cameras=cameras))
    h = Harness(world, [script, route], seed=2)
    if direction == 'reverse':  # out along the tape, a motor-off stop, then back
        h.run(6.0)
        script.command['mode'] = 'idle'
        h.run(2.5)
        script.command.update(mode='camera', direction='reverse', leg=2)
    route.cpu = dict.fromkeys(route.cpu, 0.0)
    start, frames = h.now, 0
    offsets: dict[str, list[float]] = {'lead': [], 'lead_sign': [], 'trail': []}
    while h.now < start + seconds - 1e-9:
        out = h.step()
        frames += len(out['frames'])
        if h.now - start < SETTLE[direction] or world.sample % 17:
            continue
        front, rear = windows(world)
        lead, trail = (front, rear) if direction == 'forward' else (rear, front)
        zone = 'lead_sign' if near_sign(lay, lead) else 'lead'
        offsets[zone].append(abs(world.nearest_path_offset(*lead)) * 1000)
        if not near_sign(lay, trail):
            offsets['trail'].append(abs(world.nearest_path_offset(*trail)) * 1000)
    out = {k: v * 1000 / seconds for k, v in route.cpu.items()}
    out['total'] = sum(route.cpu.values()) * 1000 / seconds
    out['fps'] = frames / seconds / 2
    out['state'] = route.state
    for key, values in offsets.items():
        out[f'{key}_mean'] = sum(values) / len(values) if values else math.nan
        out[f'{key}_max'] = max(values, default=math.nan)
    return out


def passes(frames: int = 400) -> tuple[float, float]:
    """Return µs per frame of passes 1-2 row by row (runs_of) and for the window at once."""
    lay = load_layout(layout_path('tape_1991'))
    world = WorldCore(lay, WorldParams(seed=2, rear_camera=True))
    world.on_record('steering_command', {'mode': 'wheel_speeds', 'angle': 0, 'enable': 1,
                                         'left_speed': 460, 'right_speed': 480}, 0.0)
    shots = []
    while len(shots) < frames:
        shots += list(world.step()['frames'].values())
    analyser, rows = ImageAnalyser(), np.arange(64)
    t = time.process_time()
    for f in shots:
        for r in rows:
            [(a, n) for a, n in runs_of(f[r]) if n >= analyser.p.min_run]
    by_row = (time.process_time() - t) / len(shots) * 1e6
    t = time.process_time()
    for f in shots:
        analyser._runs(f, rows)
    return by_row, (time.process_time() - t) / len(shots) * 1e6


def report(seconds: float) -> str:
    """Return the Markdown page."""
    lines = [
        '# Camera route following: CPU, and `lead` against `both` (`bench/route_cpu_bench.py`)',
        '', '```bash', f'.venv/bin/python bench/route_cpu_bench.py --seconds {seconds:g} '
        '--out bench/results/route_cpu_bench.md', '```', '',
        'Lock step on tape_1991 (circle R = 2.95 m, signs R2, P22, P21), cruise 0.47 m/s, '
        'both cameras rendered at 20 frames/s, seed 2. **forward**: a leg from the start for '
        f'{seconds:g} s. **reverse**: a 6 s forward leg, a motor-off stop (idle, 2.5 s), then '
        f'a reverse leg for {seconds:g} s, the rear camera leading. CPU: time.process_time '
        "around the route-following core's calls only (frames: `on_frame`; records: "
        'route_command and wheel_odometry; loop: the 100 Hz `tick`), ms per simulated second; '
        '% of one core at real time. Offsets: |lateral offset| of a window centre from the '
        'tape (ground truth) every 50 ms, after 8 s forward or 5 s in reverse; "off signs" '
        f'leaves out the window within {SIGN_ZONE} m of a crossing, "at signs" is that zone '
        '(the patch and branches shift any fit). Measured on a 2-core reference machine.', '',
        '| cameras | leg | frames/s per camera | frames (ms/s) | records (ms/s) | loop (ms/s) '
        '| total (ms/s) | % of a core | leading window off signs: mean / max (mm) '
        '| leading window at signs: max (mm) | trailing window off signs: mean / max (mm) '
        '| state |',
        '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for cameras in ('lead', 'both'):
        for direction in ('forward', 'reverse'):
            r = run(cameras, direction, seconds)
            lines.append(
                f'| {cameras} | {direction} | {r["fps"]:.0f} | {r["frames"]:.2f} | '
                f'{r["records"]:.2f} | {r["loop"]:.2f} | {r["total"]:.2f} | '
                f'{r["total"] / 10:.2f} | {r["lead_mean"]:.2f} / {r["lead_max"]:.2f} | '
                f'{r["lead_sign_max"]:.1f} | {r["trail_mean"]:.2f} / {r["trail_max"]:.2f} | '
                f'{r["state"]} |')
    by_row, at_once = passes()
    lines += ['', 'Image passes 1-2 (run lengths and the noise filter) on 400 rendered frames, '
              'per frame:', '', '| passes | µs per frame |', '|---|---|',
              f'| a row at a time (`runs_of` on each of 64 rows) | {by_row:.0f} |',
              f'| the whole window at once (`ImageAnalyser._runs`) | {at_once:.0f} |']
    return '\n'.join(lines) + '\n'


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seconds', type=float, default=30.0, help='simulated seconds per leg')
    ap.add_argument('--out', type=Path, help='write the page here as well')
    args = ap.parse_args()
    page = report(args.seconds)
    print(page, end='')
    if args.out:
        args.out.write_text(page)
    return 0


if __name__ == '__main__':
    sys.exit(main())
