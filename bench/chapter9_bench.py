"""Rajagopalan 1991, Chapter 9's extensions (system 15) beside route following's defaults.

Run: .venv/bin/python bench/chapter9_bench.py [--seeds 2 3 4] [--out FILE]

Each run is the world core (camera windows rendered at the camera rate, specks of noise, the
vehicle model: the kinematic Concic2 or Concic2Dynamic, App. G, by world concic2.model) with
the route-following core in camera mode and a stand-in executive (harness.CameraLegScript),
seeded (world and harness alike), in lock step, as bench/concic2_best_bench.py and
bench/concic2_curvature_bench.py run them. The error is the world's ground truth: the camera
window centre's signed distance from the tape, every 50 ms (a frame).

Experiments (the thesis's, 7.3.3 and 7.3.5, and an S-bend): the 0.065 m step, a straight tape
that steps sideways 8 m along, met at cruise (0.31 and 0.79 m/s, the ends of 7.3.3's
range); the circle R = 2.95 m from rest on
it, at 0.63 m/s; the S-bend of 1.5 m straight, 60 deg of R 3 m to the left,
0.6 m straight, 60 deg of R 2 m to the right and 3 m straight, at 0.63 and 0.79 m/s.

Quantities: peak (mm): the step's overshoot past the new tape, else the largest |error| from
the first arc's start (the circle: 5 s on, the start's transient excluded; the S-bend: to
1 m past the second arc). Steady (mm): mean |error| over the last 2.5 s (the step),
from 20 s to 30 s (the circle), over the last 1 m of the final straight (the S-bend). Within
5 mm (s): from the step, the circle's start or the S-bend's second arc's end until |error|
stays within 5 mm to the end of the run.

Configurations: the defaults (all chapter9 options off) and each option on alone:
chapter9.speed_reference 0.47 (9.3: the P gains x V / 0.47 m/s, the thesis's normal
industrial speed, 7.6) and chapter9.inflexion_curvature 0.3 per m, inflexion_frames 3 (9.5:
the predictor's curvature restarted at a change of concavity).

"No worse": an option's value is within the defaults' value plus the defaults' seed-to-seed
spread (largest minus smallest over the seeds) on that row and quantity, all seeds' means
compared; marked **worse** otherwise.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
import math
import multiprocessing
from pathlib import Path
import sys
import tempfile

from agv_nodes.harness import CameraLegScript, Harness
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import Chapter9Params, RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

MODELS = ('kinematic', 'dynamic')
STEP, AT, BAND, FRAME = 0.065, 8.0, 0.005, 17  # m, m, m, world samples per 50 ms
CONFIGS = {
    'defaults': Chapter9Params(),
    'speed law (9.3)': Chapter9Params(speed_reference=0.47),
    'inflexion (9.5)': Chapter9Params(inflexion_curvature=0.3, inflexion_frames=3),
}
# (name, kind, speed): the experiments of the module docstring.
EXPERIMENTS = [(f'step 0.065 m at {v} m/s', 'step', v) for v in (0.31, 0.79)] + [
    ('circle R 2.95 m at 0.63 m/s', 'circle', 0.63),
    ('S-bend R 3 / 0.6 / R 2 m at 0.63 m/s', 'sbend', 0.63),
    ('S-bend R 3 / 0.6 / R 2 m at 0.79 m/s', 'sbend', 0.79)]
QUANTITIES = ('peak', 'steady', 'settle')


class TapeWorld(WorldCore):
    """The world core without its marker sensor, which a tape floor without cards leaves dark."""

    def _adc(self) -> dict[str, int]:
        return {}


def tapes(*tape: tuple[list[float], str]) -> Layout:
    """Return a layout of tapes (start pose, segments as layout.py reads them), no signs."""
    body = ''.join(f'  - id: t{k}\n    start: {start}\n    width: 0.058\n'
                   f'    segments: [{segments}]\n' for k, (start, segments) in enumerate(tape))
    text = f'layout: chapter9\nvehicle: concic2\nkind: tape\ntapes:\n{body}' \
           'start: {path: t0, at: 0.3}\n'
    with tempfile.TemporaryDirectory() as folder:
        file = Path(folder) / 'chapter9.yaml'
        file.write_text(text)
        return load_layout(file)


def settle(rows: list[tuple[float, float]], t0: float) -> float:
    """Return s from `t0` until |error| stays within 5 mm (inf: outside at the end)."""
    outside = [t for t, e in rows if t >= t0 and abs(e) > BAND]
    if not outside:
        return 0.0
    return math.inf if outside[-1] >= rows[-1][0] - 1e-9 else outside[-1] - t0


def run(kind: str, model: str, speed: float, options: Chapter9Params, seed: int
        ) -> dict[str, float]:
    """Return peak, steady (mm) and settle (s) of one experiment; all inf when the tape is lost."""
    if kind == 'step':
        lay = tapes(([-1.0, 0.0, 0.0], f'{{straight: {AT + 1.0}}}'),
                    ([AT, STEP, 0.0], '{straight: 40.0}'))
        until = speed / 0.2 + AT / speed + 10.0
    elif kind == 'circle':
        # From rest on the circle (as 7.3.5): a straight leading in would lie within a window's
        # width of the circle's second lap for a metre.
        lay = tapes(([0.0, 0.0, 0.0], '{arc: 2.95, angle: 720}'))
        until = 30.0
    else:
        lay = tapes(([0.0, 0.0, 0.0], '{straight: 1.5}, {arc: 3.0, angle: 60.0}, '
                     '{straight: 0.6}, {arc: 2.0, angle: -60.0}, {straight: 3.0}'))
        arcs = (1.5, 1.5 + math.pi + 0.6, 1.5 + math.pi + 0.6 + 2.0 * math.pi / 3.0)
        until = 2.0 * (arcs[2] + 2.2) / speed + 10.0  # a cap: the run ends 2.2 m past
    world = TapeWorld(lay, WorldParams(seed=seed, concic2=Concic2Params(model=model)))
    params = replace(RouteParams(), vehicle='concic2', camera_speed=speed, chapter9=options)
    script = CameraLegScript()
    h = Harness(world, [script, RouteCore(params)], seed=seed)
    lc = world.p.concic2.camera_distance
    rows: list[tuple[float, float, float, float]] = []  # (time, x, along, signed error m)
    while h.now < until:
        h.step()
        if world.sample % FRAME:
            continue
        if script.states and script.states[-1] != 'following':
            break
        s = world.vehicle.state
        x, y = s.x + lc * math.cos(s.heading), s.y + lc * math.sin(s.heading)
        if kind == 'step':
            rows.append((h.now, x, x, y - STEP))
        else:
            along, offset, _h = world.layout.paths['t0'].project(x, y)
            rows.append((h.now, x, float(along), float(offset)))
            if kind == 'sbend' and along >= arcs[2] + 2.2:
                break
    lost = {q: math.inf for q in QUANTITIES}
    if not rows or script.states != ['following'] or (kind != 'sbend' and h.now < until - 0.1):
        return lost
    if kind == 'step':
        past = [(t, e) for t, x, _a, e in rows if x > AT]
        return {'peak': 1000.0 * max(0.0, max(e for _t, e in past)),
                'steady': 1000.0 * sum(abs(e) for t, e in past if t >= past[-1][0] - 2.5)
                / len([t for t, _e in past if t >= past[-1][0] - 2.5]),
                'settle': settle(past, past[0][0])}
    if kind == 'circle':
        start = 0.0
        errors = [(t, e) for t, _x, _a, e in rows]
        late = [abs(e) for t, e in errors if t >= 20.0]
        return {'peak': 1000.0 * max(abs(e) for t, e in errors if t >= start + 5.0),
                'steady': 1000.0 * sum(late) / len(late), 'settle': settle(errors, start)}
    errors = [(t, e) for t, _x, _a, e in rows]
    end = next((t for t, _x, a, _e in rows if a >= arcs[2]), math.inf)
    if rows[-1][2] < arcs[2] + 2.0:
        return lost
    tail = [abs(e) for _t, _x, a, e in rows if a >= rows[-1][2] - 1.0]
    return {'peak': 1000.0 * max(abs(e) for _t, _x, a, e in rows if arcs[0] <= a <= arcs[2] + 1.0),
            'steady': 1000.0 * sum(tail) / len(tail), 'settle': settle(errors, end)}


def cell(values: list[float], digits: int) -> str:
    """Return the seeds' mean (and range when they differ) of one quantity."""
    if any(math.isinf(v) for v in values):
        return 'lost' if all(math.isinf(v) for v in values) else 'never'
    mean = sum(values) / len(values)
    return f'{mean:.{digits}f}' + (f' ({min(values):.{digits}f}-{max(values):.{digits}f})'
                                   if len(values) > 1 else '')


def verdict(option: dict[str, list[float]], default: dict[str, list[float]]) -> str:
    """Return 'no worse' or the quantities worse beyond the defaults' seed spread."""
    worse = []
    for q in QUANTITIES:
        a, b = option[q], default[q]
        if any(math.isinf(v) for v in a):
            if not all(math.isinf(v) for v in b):
                worse.append(q)
            continue
        if any(math.isinf(v) for v in b):
            continue
        mean_a, mean_b = sum(a) / len(a), sum(b) / len(b)
        if mean_a > mean_b + (max(b) - min(b)):
            worse.append(q)
    return 'no worse' if not worse else '**worse**: ' + ', '.join(worse)


def _run(task: tuple) -> dict[str, float]:
    return run(*task)


def table(seeds: list[int], jobs: int = 1, experiments: list = EXPERIMENTS,
          models: tuple = MODELS) -> tuple[list[str], int]:
    """Run everything (`jobs` processes); return the table's rows and the worse count."""
    tasks = [(kind, model, speed, options, seed) for _n, kind, speed in experiments
             for model in models for options in CONFIGS.values() for seed in seeds]
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            outs = iter(pool.map(_run, tasks, chunksize=1))
    else:
        outs = (run(*task) for task in tasks)
    rows, worse = [], 0
    for name, _kind, _speed in experiments:
        for model in models:
            results = {}
            for config in CONFIGS:
                out = [next(outs) for _seed in seeds]
                results[config] = {q: [o[q] for o in out] for q in QUANTITIES}
                mark = '' if config == 'defaults' else verdict(results[config],
                                                               results['defaults'])
                worse += mark.startswith('**')
                r = results[config]
                rows.append(f'| {name} | {model} | {config} | {cell(r["peak"], 1)} | '
                            f'{cell(r["steady"], 2)} | {cell(r["settle"], 2)} | {mark} |')
                print(rows[-1], flush=True)
    return rows, worse


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', type=int, nargs='+', default=[2, 3, 4])
    ap.add_argument('--jobs', type=int, default=1, help='processes (results do not depend)')
    ap.add_argument('--out', type=Path, default=None, help='also write the table here')
    args = ap.parse_args(argv)
    command = ('.venv/bin/python bench/chapter9_bench.py '
               + ' '.join(sys.argv[1:] if argv is None else argv)).strip()
    rows, worse = table(args.seeds, args.jobs)
    intro = __doc__.split('\n\n')[2:]
    lines = ['# Chapter 9 extensions against the defaults on both CONCIC-II models', '',
             f'Command: `{command}`', '', *[' '.join(p.split()) + '\n' for p in intro],
             f'Seeds {", ".join(map(str, args.seeds))}: each cell the mean, in brackets the '
             'smallest and largest.', '',
             '| experiment | model | configuration | peak (mm) | steady (mm) | '
             'within 5 mm after (s) | against the defaults |',
             '|---|---|---|---|---|---|---|', *rows, '',
             f'Rows worse than the defaults beyond their seed spread: {worse}.']
    text = '\n'.join(lines) + '\n'
    print(text.splitlines()[-1])
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
