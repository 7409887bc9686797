"""Curvature that changes: S-bends and circles on both CONCIC-II models, ours against thesis.

Run: .venv/bin/python bench/concic2_curvature_bench.py [--quick] [--out FILE]

Each run is the world core (camera windows rendered at the camera rate, noise, the vehicle
model: the kinematic Concic2 or Concic2Dynamic, App. G) with the route-following core in camera
mode and a stand-in executive (harness.CameraLegScript), seeded, in lock step. The error is the
world's ground truth: the camera window centre's distance from the tape, every 50 ms (a frame).

Courses, the tape laid by the world's layout code (straight and arc segments). S-bend: 1.5 m of
straight, a 60 deg arc of R1 to the left, a straight of `gap` m, a 60 deg arc of R2 to the
right, 3 m of straight; the truck starts from rest on the first straight. An arc's peak is the
largest error from the window reaching the arc's start to its reaching the next arc (the first
arc: its exit and the straight after it) or, for the last, 1 m past the arc's end. Circle: the
truck set down from rest with its window on a circle of radius R (a straight into it would pass
under the window beside the circle), lap after lap; steady: the mean error from 20 s to 30 s
(as bench/concic2_best_bench.py). Smallest radius: circles of falling radius at 0.16 and
0.31 m/s with our settings; held: the truck still following after a lap.

Goals (the issue's): on every arc of R 2-3 m at 0.31-0.79 m/s a peak of at most 15 mm; on
circles of R 2.0-3.0 m a steady error of at most 2 mm at every speed; our settings no worse
than the thesis's law anywhere.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
import math
from pathlib import Path
import sys
import tempfile

from agv_nodes.harness import CameraLegScript, Harness
from agv_nodes.package_share import config_dir
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import settings_from_file
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

# Our curve settings (route following's defaults with the orientation fed back at L_a / L_c,
# the integral within 10 mm and the window predicted 0.15 s on: OURS, not our settings, for the
# road signs' sake, see parameters.yaml), and the `thesis` preset's route_following section
# (the thesis's laws, gains, image rows and set-off, Rajagopalan 1991, 7.3).
OURS = {'gain_theta': 0.484375, 'integral_band': 0.01, 'predict': 0.15}
PRESET = config_dir() / 'presets' / 'concic2_thesis.yaml'
LAWS = {'ours': replace(RouteParams(), steering=replace(RouteParams().steering, **OURS)),
        'thesis': settings_from_file(RouteParams, PRESET, 'route_following')}
MODELS = ('kinematic', 'dynamic')
SPEEDS = (0.31, 0.47, 0.63, 0.79)
# (first radius, straight between, second radius): both turning orders, R 2 and 3 m.
BENDS = ((3.0, 0.3, 2.0), (3.0, 0.9, 2.0), (2.0, 0.3, 3.0), (2.0, 0.9, 3.0))
RADII = (2.0, 2.5, 3.0)
SMALL = (1.0, 0.9, 0.8, 0.7)  # m, the smallest-radius search
SLOW = (0.16, 0.31)
ARC, LEAD, TAIL, PAST = 60.0, 1.5, 3.0, 1.0  # deg; m
PEAK, STEADY = 15.0, 2.0  # mm: the goals
FRAME = 17  # world samples (340 Hz) per ground-truth sample: 50 ms


class TapeWorld(WorldCore):
    """The world core without its marker sensor, which a tape floor without cards leaves dark."""

    def _adc(self) -> dict[str, int]:
        return {}


def tape(segments: str) -> Layout:
    """Return a one-tape layout of `segments` (layout.py's), the window 0.3 m along it."""
    text = ('layout: curvature\nvehicle: concic2\nkind: tape\ntapes:\n  - id: main\n'
            f'    start: [0.0, 0.0, 0.0]\n    width: 0.058\n    segments: [{segments}]\n'
            'start: {path: main, at: 0.3}\n')
    with tempfile.TemporaryDirectory() as folder:
        file = Path(folder) / 'curvature.yaml'
        file.write_text(text)
        return load_layout(file)


@dataclass
class Run:
    """One drive: the truck, its course and the stand-in executive."""

    harness: Harness
    world: WorldCore
    script: CameraLegScript

    @property
    def following(self) -> bool:
        """Return whether route following has only ever been following (no stop)."""
        return self.script.states == ['following']

    def window(self) -> tuple[float, float]:
        """Ground truth now: (m along the tape, |offset| m) of the camera window centre."""
        s, lc = self.world.vehicle.state, self.world.p.concic2.camera_distance
        along, offset, _h = self.world.layout.paths['main'].project(
            s.x + lc * math.cos(s.heading), s.y + lc * math.sin(s.heading))
        return float(along), abs(float(offset))

    def frames(self, until: float):
        """Yield (time, m along, |offset| m) every frame until sim time `until` or a stop."""
        h = self.harness
        while h.now < until:
            h.step()
            if self.world.sample % FRAME == 0:
                if self.script.states and self.script.states[-1] != 'following':
                    return
                yield (h.now, *self.window())


def drive(lay: Layout, model: str, speed: float, params: RouteParams) -> Run:
    """Put the CONCIC-II `model` on `lay`, route following (`params`) in camera mode."""
    world = TapeWorld(lay, WorldParams(seed=2, concic2=Concic2Params(model=model)))
    route = RouteCore(replace(params, vehicle='concic2', camera_speed=speed))
    script = CameraLegScript()
    return Run(Harness(world, [script, route], seed=2), world, script)


def bend(r1: float, gap: float, r2: float, model: str, speed: float,
         params: RouteParams) -> tuple[float, float] | None:
    """Return the peak (mm) on each arc of an S-bend (see the module docstring); None: lost."""
    lay = tape(f'{{straight: {LEAD}}}, {{arc: {r1}, angle: {ARC}}}, {{straight: {gap}}}, '
               f'{{arc: {r2}, angle: {-ARC}}}, {{straight: {TAIL}}}')
    a1 = LEAD
    a2 = a1 + math.radians(ARC) * r1 + gap
    end = a2 + math.radians(ARC) * r2 + PAST
    run = drive(lay, model, speed, params)
    peaks = [0.0, 0.0]
    reached = False
    for _t, along, offset in run.frames(2.0 * (end + 1.0) / speed + 10.0):
        if along >= end:
            reached = True
            break
        if along >= a1:
            k = 0 if along < a2 else 1
            peaks[k] = max(peaks[k], 1000.0 * offset)
    return (peaks[0], peaks[1]) if reached and run.following else None


def circle(radius: float, model: str, speed: float, params: RouteParams,
           laps: float = 0.0) -> tuple[float, float] | None:
    """Return (steady, worst) mm on a circle of `radius` from rest; None: lost.

    laps 0: steady is the mean error from 20 s to 30 s and worst the largest then. laps > 0:
    run until the axle has gone that many laps; steady is the mean, worst the largest error
    over the last half lap.
    """
    turns = 3 if laps == 0 else math.ceil(laps) + 1
    lay = tape(f'{{arc: {radius}, angle: {360.0 * turns}}}')
    run = drive(lay, model, speed, params)
    lap = 2.0 * math.pi * radius
    errors: list[tuple[float, float]] = []  # (time or distance past the lead, error mm)
    if laps == 0:
        for t, _along, offset in run.frames(30.0):
            if t >= 20.0:
                errors.append((t, 1000.0 * offset))
        if not (run.following and errors and errors[-1][0] >= 29.9):
            return None
    else:
        travelled = 0.0  # m, the axle's
        for _t, _along, offset in run.frames(2.0 * laps * lap / speed + 10.0):
            travelled = run.world.vehicle.state.distance
            errors.append((travelled, 1000.0 * offset))
            if travelled >= laps * lap:
                break
        if not (run.following and travelled >= laps * lap):
            return None
        errors = [(s, e) for s, e in errors if s >= (laps - 0.5) * lap]
    values = [e for _s, e in errors]
    return sum(values) / len(values), max(values)


def fmt(value: float | None, digits: int = 1) -> str:
    """Return a cell: the number, or 'lost' (the tape left the window: motor-off stop)."""
    return 'lost' if value is None else f'{round(value, digits) + 0.0:.{digits}f}'


def met(ok: bool) -> str:
    """Return the goal cell."""
    return 'yes' if ok else '**no**'


def bend_case(case: tuple) -> tuple[float, float] | None:
    """Run bend() on (r1, gap, r2, model, speed, law name): a task for the pool."""
    *course, law = case
    return bend(*course, LAWS[law])


def circle_case(case: tuple) -> tuple[float, float] | None:
    """Run circle() on (radius, model, speed, law name): a task for the pool."""
    *course, law = case
    return circle(*course, LAWS[law])


def smallest_case(case: tuple[str, float]) -> tuple[tuple | None, list[str]]:
    """Return the smallest of SMALL our settings hold for (model, speed), and each tried."""
    model, speed = case
    held, tried = None, []
    for radius in SMALL:
        got = circle(radius, model, speed, LAWS['ours'], laps=1.0)
        tried.append(f'{radius:.2f} {"held" if got else "lost"}'
                     + (f' ({got[1]:.0f} mm)' if got else ''))
        if got is None:
            break
        held = (radius, got)
    return held, tried


def bend_rows(speeds: tuple[float, ...], bends: tuple, run: Callable
              ) -> tuple[list[str], list[bool]]:
    """Return the S-bend table's rows and, per row, whether our settings met the goals there."""
    cases = [(*b, model, speed) for b in bends for model in MODELS for speed in speeds]
    got = list(run(bend_case, [(*c, law) for c in cases for law in LAWS]))
    rows, goals = [], []
    for k, (r1, gap, r2, model, speed) in enumerate(cases):
        ours, thesis = got[2 * k], got[2 * k + 1]
        ok = ours is not None and max(ours) <= PEAK and (
            thesis is None or all(o <= t for o, t in zip(ours, thesis, strict=True)))
        cells = [fmt(p) for p in (ours or (None, None))] + \
            [fmt(p) for p in (thesis or (None, None))]
        rows.append(f'| R {r1:.1f} left, {gap:.1f} m, R {r2:.1f} right | {model} | '
                    f'{speed:.2f} | ' + ' | '.join(cells) + f' | {met(ok)} |')
        goals.append(ok)
        print(rows[-1], flush=True)
    return rows, goals


def circle_rows(speeds: tuple[float, ...], radii: tuple[float, ...], run: Callable
                ) -> tuple[list[str], list[bool]]:
    """Return the circle table's rows and, per row, whether our settings met the goals there."""
    cases = [(radius, model, speed) for radius in radii for model in MODELS for speed in speeds]
    got = list(run(circle_case, [(*c, law) for c in cases for law in LAWS]))
    rows, goals = [], []
    for k, (radius, model, speed) in enumerate(cases):
        ours, thesis = got[2 * k], got[2 * k + 1]
        ok = ours is not None and ours[0] <= STEADY and (thesis is None or ours[0] <= thesis[0])
        cells = [fmt(r[j] if r else None) for r in (ours, thesis) for j in (0, 1)]
        rows.append(f'| {radius:.1f} | {model} | {speed:.2f} | ' + ' | '.join(cells)
                    + f' | {met(ok)} |')
        goals.append(ok)
        print(rows[-1], flush=True)
    return rows, goals


def smallest_rows(run: Callable) -> list[str]:
    """Return the rows of the smallest circle our settings hold, per slow speed and model."""
    cases = [(model, speed) for model in MODELS for speed in SLOW]
    rows = []
    for (model, speed), (held, tried) in zip(cases, run(smallest_case, cases), strict=True):
        cells = ('none', '-', '-') if held is None else (
            f'{held[0]:.2f}', fmt(held[1][0]), fmt(held[1][1]))
        rows.append(f'| {model} | {speed:.2f} | ' + ' | '.join(cells) + ' | '
                    + ', '.join(tried) + ' |')
        print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true',
                    help='the worst cases only: 0.79 m/s, the 0.3 m straights, R 2.0 m')
    ap.add_argument('--out', type=Path, default=None, help='also write the tables here')
    ap.add_argument('--jobs', type=int, default=1,
                    help='runs at once, each in a process of its own (the same results)')
    args = ap.parse_args(argv)
    command = ('.venv/bin/python bench/concic2_curvature_bench.py '
               + ' '.join(sys.argv[1:] if argv is None else argv)).strip()
    speeds = (0.79,) if args.quick else SPEEDS
    bends = tuple(b for b in BENDS if b[1] == 0.3) if args.quick else BENDS
    with ProcessPoolExecutor(args.jobs) as pool:
        run = pool.map if args.jobs > 1 else map
        bend_table, bend_goals = bend_rows(speeds, bends, run)
        circle_table, circle_goals = circle_rows(speeds, RADII[:1] if args.quick else RADII,
                                                 run)
        small = [] if args.quick else smallest_rows(run)
    d = LAWS['ours'].steering
    goals = bend_goals + circle_goals
    lines = ['# Curvature that changes: S-bends and circles on both CONCIC-II models', '',
             f'Command: `{command}`', '',
             *[' '.join(p.split()) + '\n' for p in __doc__.split('\n\n')[2:]],
             "ours: route following's defaults but three settings; camera steering PI, "
             f'gain_d {d.gain_d}, '
             f'gain_theta {d.gain_theta}, gain_i {d.gain_i} {d.integral_form}, '
             f'schedule_speed {d.schedule_speed}, integral_band {d.integral_band}, '
             f'predict {d.predict} s, wheel_lag {d.wheel_lag} s, curvature_filter '
             f"{d.curvature_filter}; all 64 image rows. thesis: the `thesis` preset's "
             'route_following settings (config/presets/concic2_thesis.yaml).', '',
             '## S-bends: peak per arc (mm)', '',
             '| S-bend | vehicle | speed (m/s) | ours, 1st arc | ours, 2nd arc | '
             'thesis, 1st arc | thesis, 2nd arc | goal met |', '|---|---|---|---|---|---|---|---|',
             *bend_table, '', '## Circles: steady error (mm), 20-30 s', '',
             '| R (m) | vehicle | speed (m/s) | ours, steady | ours, worst | '
             'thesis, steady | thesis, worst | goal met |', '|---|---|---|---|---|---|---|---|',
             *circle_table, '']
    if small:
        lines += ['## The smallest circle held with our settings (Table 6.1 asks for 0.5 m)', '',
                  'A window L_c = 0.64 m ahead of the axle is on a circle of radius R only with '
                  'the axle sqrt(R^2 - L_c^2) from its centre, which needs R > 0.64 m: '
                  "Table 6.1's 0.5 m cannot be held with the window on the tape. Steady and "
                  'worst: mean and largest error over the second half of the lap.', '',
                  '| vehicle | speed (m/s) | smallest R held (m) | steady (mm) | worst (mm) | '
                  'radii tried |', '|---|---|---|---|---|---|', *small, '']
    lines.append(f'Goals met in {sum(goals)} of {len(goals)} rows.')
    text = '\n'.join(lines) + '\n'
    print(text.splitlines()[-1])
    if args.out:
        args.out.write_text(text)
    return 0 if all(goals) else 1


if __name__ == '__main__':
    sys.exit(main())
