"""Rajagopalan 1991, Chapter 9's extensions (system 15) beside route following's defaults.

Run: .venv/bin/python bench/chapter9_bench.py [--seeds 2 3 4] [--jobs N] [--out FILE]

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
chapter9.speed_reference 0.47 m/s (9.3, the thesis's normal industrial speed, 7.6) in the two
speed_form readings that change the law (the text's own, once, is the plain law): gains (the P
gains x V / 0.47) and per_time (x 0.47 / V); chapter9.inflexion_curvature 0.3 per m,
inflexion_frames 3 (9.5: the window predictor's curvature restarted at a change of
concavity), judged against route following's own predictor on (steering.predict 0.15 s, off by
default, which the inflexion acts on: with it off the option changes nothing); and on
the dynamic model only (the kinematic one has no LM628 loops) the world's concic2.cross_coupling
1.0 (9.2.1) and cross_coupling 1.0 with cartesian_gain 1.0 (9.2.2, the Cartesian loop on top of
the cross-coupled one, as Fig. 9.2 draws them).

Reference-point dual guidance (9.6): the dual-camera experiments of bench/dual_camera_bench.py
(7.4, Table 5.4: both windows 0.05 m to one side, or -0.03 / +0.06 m, on a straight and on the
R 3.0 m circle, set down at cruise 0.47 m/s, the thesis's dual law), with the gains' switch at
the front end (the defaults) and at c = 0.64 m behind the leading window, the axle centre O
(chapter9.reference_point). Quantities: each window's time until it stays within 10 mm, the
larger overshoot past the tape of the two windows.

"No worse": an option's value is within the defaults' value plus the defaults' seed-to-seed
spread (largest minus smallest over the seeds) on that row and quantity, all seeds' means
compared; marked **worse** otherwise.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field, replace
import math
import multiprocessing
from pathlib import Path
import subprocess
import sys
import tempfile

from agv_nodes.harness import CameraLegScript, Harness
from agv_nodes.route_following.camera_guidance import ImageAnalyser
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.dual_camera import DualCameraGuidance
from agv_nodes.route_following.settings import Chapter9Params, RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dual_camera_bench as dual_bench  # noqa: E402  (bench/ is no package)

MODELS = ('kinematic', 'dynamic')
STEP, AT, BAND, FRAME = 0.065, 8.0, 0.005, 17  # m, m, m, world samples per 50 ms


@dataclass(frozen=True)
class Config:
    """One configuration: options over the defaults, the models it acts on, what it is against."""

    options: Chapter9Params = field(default_factory=Chapter9Params)  # route_following chapter9
    wheels: tuple[tuple[str, float], ...] = ()  # the world's concic2 (the wheel loops of 9.2)
    steering: tuple[tuple[str, float], ...] = ()  # route following's steering
    models: tuple[str, ...] = MODELS
    against: str = 'defaults'  # the row it is judged against ('': a baseline, not judged)


PREDICT = (('predict', 0.15),)  # s: route following's window predictor on (steering.predict)
CONFIGS: dict[str, Config] = {
    'defaults': Config(against=''),
    'speed law (9.3), gains': Config(Chapter9Params(speed_reference=0.47, speed_form='gains')),
    'speed law (9.3), per_time': Config(Chapter9Params(speed_reference=0.47,
                                                       speed_form='per_time')),
    'predictor (steering.predict 0.15 s)': Config(steering=PREDICT, against=''),
    'inflexion (9.5) on the predictor': Config(
        Chapter9Params(inflexion_curvature=0.3, inflexion_frames=3), steering=PREDICT,
        against='predictor (steering.predict 0.15 s)'),
    'cross-coupled (9.2.1)': Config(wheels=(('cross_coupling', 1.0),), models=('dynamic',)),
    'Cartesian (9.2.2)': Config(wheels=(('cross_coupling', 1.0), ('cartesian_gain', 1.0)),
                                models=('dynamic',)),
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


def run(kind: str, model: str, speed: float, options: Chapter9Params, seed: int,
        wheels: tuple[tuple[str, float], ...] = (), steering: tuple[tuple[str, float], ...] = ()
        ) -> dict[str, float]:
    """Return peak, steady (mm) and settle (s) of one experiment; all inf when the tape is lost.

    `wheels`: world concic2 options (the wheel loops of 9.2), `steering`: route following's
    steering options, each (key, value) over the defaults.
    """
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
    world = TapeWorld(lay, WorldParams(seed=seed, concic2=replace(Concic2Params(model=model),
                                                                  **dict(wheels))))
    params = replace(RouteParams(), vehicle='concic2', camera_speed=speed, chapter9=options)
    params = replace(params, steering=replace(params.steering, **dict(steering)))
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


# Reference-point dual guidance (9.6): the gains switch where the tape crosses c, here the
# axle centre O (L1 = L2 = L_c, the middle of the axis), against the front end (the defaults).
REFERENCE = 0.64  # m behind the leading window
DUAL_QUANTITIES = ('front', 'rear', 'overshoot')


def dual_run(radius: float, front: float, rear: float, model: str, reference: float, seed: int,
             duration: float = 15.0) -> dict[str, float]:
    """Return front and rear time within 0.01 m (s), the worse window's overshoot (mm).

    The dual-camera experiments of bench/dual_camera_bench.py (Rajagopalan 1991, 7.4, Table
    5.4): the truck set down at cruise 0.47 m/s with its windows `front` / `rear` m left of the
    tape, the thesis's dual law (DualCameraParams' defaults) with the gains' switch at
    `reference` m behind the leading window (0: the front end, the thesis's).
    """
    world = dual_bench.TapeWorld(dual_bench.tape_layout(radius),
                                 WorldParams(seed=seed, rear_camera=True))
    world.vehicle = dual_bench.VEHICLES[model](world.p.concic2)
    dual_bench.place(world, front, rear, dual_bench.SPEED)
    analysers = {'front': ImageAnalyser(RouteParams().image),
                 'rear': ImageAnalyser(RouteParams().image)}
    law = DualCameraGuidance()
    law.reference_point = reference
    trace, last = [], None
    while world.time < duration:
        frames = world.step()['frames']
        if not frames:
            continue
        m = {name: analysers[name].analyse(frame) for name, frame in frames.items()}
        dt = world.time - last if last is not None else 1.0 / world.p.camera_rate
        last = world.time
        theta = law.update(m['front'], m['rear'], dt)
        if theta is None:
            return {q: math.inf for q in DUAL_QUANTITIES}
        left, right = law.wheel_speeds(dual_bench.SPEED, theta)
        world.on_record('steering_command', {
            'mode': 'wheel_speeds', 'angle': 0, 'enable': 1,
            'left_speed': int(round(left * 1000)), 'right_speed': int(round(right * 1000))},
            world.time)
        trace.append((world.time, *dual_bench.window_offsets(world)))
    return {'front': dual_bench.settle_time(trace, 1), 'rear': dual_bench.settle_time(trace, 2),
            'overshoot': 1000.0 * float(max(dual_bench.overshoot(trace, 1),
                                            dual_bench.overshoot(trace, 2)))}


def _dual(task: tuple) -> dict[str, float]:
    return dual_run(*task)


def dual_table(seeds: list[int], jobs: int = 1, models: tuple = MODELS
               ) -> tuple[list[str], int]:
    """Run the dual experiments at the front end and at REFERENCE; the rows and worse count."""
    tasks = [(radius, front, rear, model, reference, seed)
             for _n, radius, front, rear, _t in dual_bench.SCENARIOS for model in models
             for reference in (0.0, REFERENCE) for seed in seeds]
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            outs = iter(pool.map(_dual, tasks, chunksize=1))
    else:
        outs = (dual_run(*task) for task in tasks)
    rows, worse = [], 0
    for name, *_rest in dual_bench.SCENARIOS:
        for model in models:
            results = {}
            for config in ('front end (defaults)', f'reference point c {REFERENCE} m (9.6)'):
                out = [next(outs) for _seed in seeds]
                results[config] = {q: [o[q] for o in out] for q in DUAL_QUANTITIES}
                mark = ('' if config.startswith('front') else
                        verdict(results[config], results['front end (defaults)'],
                                DUAL_QUANTITIES))
                worse += mark.startswith('**')
                r = results[config]
                rows.append(f'| {name} | {model} | {config} | {cell(r["front"], 2)} | '
                            f'{cell(r["rear"], 2)} | {cell(r["overshoot"], 1)} | {mark} |')
                print(rows[-1], flush=True)
    return rows, worse


def held(result: dict[str, list[float]]) -> bool:
    """Return whether every seed's run kept the tape (a peak measured)."""
    return not any(math.isinf(v) for v in result['peak'])


def cell(values: list[float], digits: int, held: bool = False) -> str:
    """Return the seeds' mean (and range when they differ) of one quantity.

    inf: 'lost' (the run lost the tape), or 'never' back within the band where the tape was
    `held`; some seeds only: 'never'.
    """
    if any(math.isinf(v) for v in values):
        return 'lost' if all(math.isinf(v) for v in values) and not held else 'never'
    mean = sum(values) / len(values)
    return f'{mean:.{digits}f}' + (f' ({min(values):.{digits}f}-{max(values):.{digits}f})'
                                   if len(values) > 1 else '')


def verdict(option: dict[str, list[float]], default: dict[str, list[float]],
            quantities: tuple[str, ...] = QUANTITIES) -> str:
    """Return 'no worse' or the quantities worse beyond the defaults' seed spread."""
    worse = []
    for q in quantities:
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
    tasks = [(kind, model, speed, c.options, seed, c.wheels, c.steering)
             for _n, kind, speed in experiments for model in models
             for c in CONFIGS.values() if model in c.models for seed in seeds]
    if jobs > 1:
        with multiprocessing.Pool(jobs) as pool:
            outs = iter(pool.map(_run, tasks, chunksize=1))
    else:
        outs = (run(*task) for task in tasks)
    rows, worse = [], 0
    for name, _kind, _speed in experiments:
        for model in models:
            results = {}
            for config, c in CONFIGS.items():
                if model not in c.models:
                    continue
                out = [next(outs) for _seed in seeds]
                results[config] = {q: [o[q] for o in out] for q in QUANTITIES}
                mark = verdict(results[config], results[c.against]) if c.against else ''
                worse += mark.startswith('**')
                r = results[config]
                rows.append(f'| {name} | {model} | {config} | {cell(r["peak"], 1)} | '
                            f'{cell(r["steady"], 2)} | {cell(r["settle"], 2, held(r))} | '
                            f'{mark} |')
                print(rows[-1], flush=True)
    return rows, worse


def code_version() -> str:
    """Return the commit the code was run at, and the files changed from it if any."""
    root = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=root, text=True,
                              capture_output=True, check=True).stdout.strip()
        changed = subprocess.run(['git', 'status', '--porcelain', '--', 'agv_nodes', 'bench'],
                                 cwd=root, text=True, capture_output=True,
                                 check=True).stdout.split('\n')
    except (OSError, subprocess.CalledProcessError):
        return 'not a git checkout'
    files = [line[3:] for line in changed if line.strip() and line[3:].endswith(('.py', '.yaml'))]
    return f'commit {head}' + (f', with these files changed from it: {", ".join(files)}'
                               if files else '')


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', type=int, nargs='+', default=[2, 3, 4])
    ap.add_argument('--jobs', type=int, default=1, help='processes (results do not depend)')
    ap.add_argument('--out', type=Path, default=None, help='also write the table here')
    args = ap.parse_args(argv)
    command = ('.venv/bin/python bench/chapter9_bench.py '
               + ' '.join(sys.argv[1:] if argv is None else argv)).strip()
    code = code_version()  # what the runs load, before they start
    rows, worse = table(args.seeds, args.jobs)
    dual_rows, dual_worse = dual_table(args.seeds, args.jobs)
    intro = __doc__.split('\n\n')[2:]
    lines = ['# Chapter 9 extensions against the defaults on both CONCIC-II models', '',
             f'Command: `{command}`', '', f'Code: {code}', '',
             *[' '.join(p.split()) + '\n' for p in intro],
             f'Seeds {", ".join(map(str, args.seeds))}: each cell the mean, in brackets the '
             'smallest and largest.', '',
             '| experiment | model | configuration | peak (mm) | steady (mm) | '
             'within 5 mm after (s) | against the defaults |',
             '|---|---|---|---|---|---|---|', *rows, '',
             f'Rows worse than the defaults beyond their seed spread: {worse}.', '',
             '## Reference-point dual guidance (9.6)', '',
             '| start | model | gains switch at | front within 10 mm (s) | rear within 10 mm (s) '
             '| overshoot (mm) | against the defaults |',
             '|---|---|---|---|---|---|---|', *dual_rows, '',
             f'Rows worse than the front end beyond its seed spread: {dual_worse}.']
    text = '\n'.join(lines) + '\n'
    print(text.splitlines()[-1])
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
