"""The thesis's single-camera experiments on both CONCIC-II models: Rajagopalan 1991, 7.3, 8.4.

Run: .venv/bin/python bench/concic2_thesis_bench.py [--out FILE]

Each experiment runs the world core (camera windows rendered at the camera rate, noise, the
vehicle model) with the route-following core in camera mode (route_command mode 'camera'),
seeded, in lock step, once on the kinematic Concic2 and once on Concic2Dynamic (Huang's
model, App. G, with its two LM628 loops; bench/concic2_thesis_runs.py). Route following runs
the `thesis` preset (config/presets/concic2_thesis.yaml, read as the node reads it): PI 2.5 /
0.07 with the integral times the frame interval (Eq. 5.6), no orientation feedback, 3 image
rows, the drive's trapezoid starting the wheels alike; on curves the thesis's 1.0 / 0.07
(7.3.1, 7.6). Errors are ground truth at the camera window centre, sampled every 50 ms.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
import math
from pathlib import Path
import sys

from concic2_thesis_runs import (
    ACCELERATION_0024,
    DRIVE,
    HALF_WINDOW,
    STEP,
    THESIS,
    VEHICLES,
    Executive,
    Result,
    TapeWorld,
    circle,
    circle_floor,
    cruise,
    drive,
    law,
    payload,
    recovery,
    step,
    strips,
    thesis,
)

from agv_nodes.route_following.settings import ImageParams

# What the other benches take from here (bench/concic2_best_bench.py, identification_*.py).
__all__ = ['VEHICLES', 'Executive', 'Result', 'TapeWorld', 'circle', 'circle_floor', 'cruise',
           'fmt', 'law', 'recovery', 'step', 'strips']
CURVE = thesis(gain_d=1.0)  # P 1.0, I 0.07: the thesis's setting for curves (7.6)
# The "0.024" reading's trapezoid; the encoder check given 1 s (its 0.3 s assumes the 0.3 m/s^2
# trapezoid: at 0.112 the dynamic model's first count comes later and the check stops the truck).
SLOW = {'acceleration': ACCELERATION_0024, 'encoder_time': 1.0}


def fmt(value: float, digits: int = 1) -> str:
    """Return a cell: the number, 'never' for inf, '-' for nan."""
    if math.isnan(value):
        return '-'
    if math.isinf(value):
        return 'never'
    return f'{round(value, digits) + 0.0:.{digits}f}'  # + 0.0: no "-0.0"


def held(r: Result) -> str:
    """Return 'held' or 'lost' (the tape left the window: motor-off stop)."""
    return 'held' if r.held else 'lost'


def over_mm(r: Result) -> str:
    """Return the step's overshoot in mm."""
    return fmt(r.overshoot * STEP * 10.0)


def over_window(r: Result) -> str:
    """Return the step's overshoot as % of the window's +-0.1 m (the thesis's 80 % reading)."""
    return fmt(r.overshoot * STEP / HALF_WINDOW)


def loads(pair: tuple[Result, Result] | None) -> str:
    """Return the start-up's worst offset with load / without, mm, and how much smaller."""
    if pair is None:
        return '- (no mass)'
    loaded, empty = pair
    return (f'{fmt(loaded.worst, 0)} / {fmt(empty.worst, 0)}: '
            f'{fmt(100.0 * (1.0 - loaded.worst / empty.worst), 0)} % smaller')


Cell = Callable[[Result], str]
STEP_CELLS: list[tuple[str, str, Cell]] = [
    ('tape', 'held', held),
    ('overshoot (mm)', '"10 %": 10 mm of the +-0.1 m window (its 80 % is 0.08 m, 7.3.2)', over_mm),
    ('overshoot (% of the 0.065 m step)', '"10 %" of the step: 10', lambda r: fmt(r.overshoot)),
    ('overshoot (% of the +-0.1 m window)', '10', over_window),
    ('within 5 mm after (s)', 'about 3.0 at 0.63 m/s, within 3 at 0.785 (8.4.1)',
     lambda r: fmt(r.settle, 2)),
    ('steady error (mm)', '5', lambda r: fmt(r.steady))]
START_CELLS: list[tuple[str, str, Cell]] = [
    ('tape', 'held', held),
    ('worst error in the start-up (mm)', 'grows, then one overshoot; below 100',
     lambda r: fmt(r.worst, 0)),
    ('when (s)', 'while the drive ramps (0-4 s)', lambda r: fmt(r.worst_at, 1)),
    ('within 5 mm after the start (s)', 'start-up error gone in 3 s (8.4.1)',
     lambda r: fmt(r.settle, 2)),
    ('steady error, last 10 s (mm)', '5 (S3, 8.4.1)', lambda r: fmt(r.steady))]
S5_CELLS: list[tuple[str, str, Cell]] = [
    ('tape', 'held', held), ('worst error (mm)', '80 at the start', lambda r: fmt(r.worst, 0)),
    ('within 5 mm after (s)', 'satisfactory', lambda r: fmt(r.settle, 2))]
CIRCLE_CELLS: list[tuple[str, str, Cell]] = [
    ('tape', 'followed', held),
    ('mean error after 20 s (mm)', 'no figure', lambda r: fmt(r.steady)),
    ('worst error (after 20 s if held) (mm)', 'no figure', lambda r: fmt(r.worst))]

# (experiment, function, arguments after the vehicle, [(quantity, thesis, cell)])
EXPERIMENTS = [
    (f'S6: 0.065 m step at {v} m/s (7.3.3, Fig. 7.8a)', step, (v, THESIS.steering), STEP_CELLS)
    for v in (0.31, 0.47, 0.63, 0.79)] + [
    ('S1: the same step at 0.63 m/s, P 2.5 (7.3.1, Fig. 7.4)', step,
     (0.63, thesis(law='p', gain_i=0.0)),
     [('overshoot (mm)', 'no figure (PI preferred)', over_mm),
      ('steady error (mm)', 'larger than PI', lambda r: fmt(r.steady))]),
    ('S2, S3: from rest to 0.79 m/s, 0.02 m off a straight (7.3.2, Fig. 7.5a, 8.4.1)', cruise,
     (0.79, THESIS.steering, 0.02), START_CELLS),
    ('S4: the same start with the 250 lb payload and without (7.3.2, Fig. 7.6)', payload,
     (0.79, THESIS.steering, 0.02),
     [('worst error with / without load (mm)', '33 % smaller with load', loads)]),
    ('S5: -0.08 m and +40 deg at 0.471 m/s (7.3.2, Fig. 7.7)', recovery,
     (-0.08, 40.0, THESIS.steering), S5_CELLS),
    ('S5 mirrored: +0.08 m and -40 deg', recovery, (0.08, -40.0, THESIS.steering),
     S5_CELLS[:1]),
    ('circle R = 2.95 m at 0.63 m/s from rest, P 1.0 (7.3.5, Fig. 7.10)', circle,
     (0.63, CURVE), CIRCLE_CELLS),
    ('S9: circle R = 2.0 m at 0.93 m/s, P 1.0 (Table 6.1)', circle, (0.93, CURVE, 2.0),
     CIRCLE_CELLS),
    ('S9: circle R = 1.7 m at 0.93 m/s, P 1.0 (6.4, 8.5)', circle, (0.93, CURVE, 1.7),
     CIRCLE_CELLS),
] + [
    (f'Table 6.1 minimum radius: circle R = {r} m at 0.16 m/s, P 1.0', circle,
     (0.16, CURVE, r), CIRCLE_CELLS[:1] + CIRCLE_CELLS[2:]) for r in (0.5, 0.7, 1.0)]

# The readings left open, each against the preset's: (reading, function, arguments, cells).
READINGS = [
    ('integral per frame (Eq. 5.8 as printed): step at 0.63 m/s', step,
     (0.63, thesis(integral_form='per_frame')), STEP_CELLS[:2] + STEP_CELLS[4:5]),
    ('integral per frame: step at 0.79 m/s', step, (0.79, thesis(integral_form='per_frame')),
     STEP_CELLS[:2] + STEP_CELLS[4:5]),
    ('integral per frame: S5', recovery, (-0.08, 40.0, thesis(integral_form='per_frame')),
     S5_CELLS[:1]),
    ('integral per frame: from rest to 0.79 m/s', cruise,
     (0.79, thesis(integral_form='per_frame'), 0.02), START_CELLS[1:4]),
    ('integral per frame: circle R = 2.95 m at 0.63 m/s, P 1.0', circle,
     (0.63, thesis(gain_d=1.0, integral_form='per_frame')), CIRCLE_CELLS),
    ('integral per frame, our set-off ramp: S9, R = 2.0 m at 0.93 m/s, P 1.0', circle,
     (0.93, thesis(gain_d=1.0, integral_form='per_frame', set_off_acceleration=0.2), 2.0),
     CIRCLE_CELLS),
    ('our set-off ramp alone: S9, R = 2.0 m at 0.93 m/s, P 1.0', circle,
     (0.93, thesis(gain_d=1.0, set_off_acceleration=0.2), 2.0), CIRCLE_CELLS),
    ('integral per frame, P 2.5: circle R = 0.7 m at 0.16 m/s', circle,
     (0.16, thesis(integral_form='per_frame'), 0.7), CIRCLE_CELLS[:1] + CIRCLE_CELLS[2:]),
    ('integral per frame, P 2.5: circle R = 1.0 m at 0.16 m/s', circle,
     (0.16, thesis(integral_form='per_frame'), 1.0), CIRCLE_CELLS[:1] + CIRCLE_CELLS[2:]),
    ('"0.024" through Eq. 6.12 (trapezoid 0.112 m/s^2): step at 0.63 m/s', step,
     (0.63, THESIS.steering), STEP_CELLS[:2] + STEP_CELLS[4:5],
     SLOW),
    ('"0.024" through Eq. 6.12: from rest to 0.79 m/s', cruise, (0.79, THESIS.steering, 0.02),
     START_CELLS[:4], SLOW),
    ('all 64 image rows: step at 0.63 m/s', step, (0.63, THESIS.steering),
     STEP_CELLS[1:2] + STEP_CELLS[5:], {'image': ImageParams(rows=[])}),
    ('our set-off ramp (set_off_acceleration 0.2): from rest to 0.79 m/s', cruise,
     (0.79, thesis(set_off_acceleration=0.2), 0.02), START_CELLS[1:4]),
    ('our set-off ramp: S5', recovery, (-0.08, 40.0, thesis(set_off_acceleration=0.2)),
     S5_CELLS),
]


NOTES = [
    'Where the models land on the thesis, and where not and why (the readings: '
    'docs/references.md, Rajagopalan 1991: readings by evidence):', '',
    '- "10 %" (S6). The thesis states errors as shares of its window: 0.01 m is "5 % of the '
    'window dimension" (7.4), -0.08 m "80 % of the maximum value of the window dimension" '
    '(7.3.2), the window "+-0.1 m" (8.7). Read so, 10 % is 10 mm; read as a share of the step, '
    '6.5 mm. With the preset the kinematic model overshoots 11-17 mm at 0.31-0.79 m/s: near '
    'the first reading at every speed, never within the second. The dynamic model overshoots '
    '12-50 mm, more the faster it goes: its yaw rate lags the wheels asked for by its servo '
    'loop (0.198 s, the drive table) where the kinematic one lags 0.051 s, and a lag costs the '
    "loop damping in proportion to the distance travelled in it. Without lags the law's "
    "damping is (L_c / 2) sqrt(G / L_a), 0.9 at G = 2.5 rad/m (the caster law psi' = V "
    "theta_s / L_a, the window L_c ahead): the overshoot is the lags' and the integral's.",
    "- Settling and steady error. Back within 5 mm in 1.5-4.0 s against the thesis's about 3 "
    's. Steady errors of about 1 mm against its 5 mm: ground truth here, while the thesis read '
    'its own camera, which measured the 0.065 m step as 0.070 m (7.3.3) and fits 3 rows to '
    'within 3 mm (8.3).',
    '- Start-up (S2, S3). The thesis saw the offset grow while the drive ramped up (0-4 s), '
    "then one overshoot. The models' wheels are alike: while the trapezoid masks the steering "
    'the truck keeps the offset it started with (worst 20 mm, the start), then steers in '
    '(within 5 mm after 3.8-3.9 s). Only the per-frame integral gives a larger transient here '
    '(39 and 62 mm at 3.2-3.4 s, as the wheels reach cruise): what it gathered during the ramp. '
    "S4's 33 % (a transient smaller with load) has no transient to act on with the preset.",
    '- S5 (-0.08 m, 40 deg). Lost on both models with the preset: with the wheels ramping '
    'alike the window centre moves sideways at sin 40 = 0.64 of the distance run, and leaves '
    'the 125 mm half window before the drive lets the steering act. With our set-off ramp '
    '(0.2 m/s^2) the kinematic model holds it (worst 109 mm) and the dynamic one, turning '
    'later, does not. The thesis does not say how its truck set off for this test.',
    "- Circles. On R = 2.95 m with the thesis's curve gains (P 1.0, I 0.07) the preset leaves "
    "23 mm after 20-30 s: under Eq. 5.6 the integral's corner is G3 / G2 = 0.07 per s (14 s), "
    'and the caster angle the curve needs (0.107 rad) takes 1.5 m s of integrated offset. The '
    'per-frame integral (x 20 at 20 frames/s) leaves 0.8 and 3.3 mm, within the thesis\'s "less '
    'than 5 % of the image window" (8.7). Here the printed Eq. 5.8 lands and Eq. 5.6 does not.',
    '- S9 (0.93 m/s on R = 2.0 m and 1.7 m). Lost with the preset: the trapezoid runs the '
    'truck straight for 3 s while it reaches cruise. With our set-off ramp and the per-frame '
    'integral both models hold R = 2.0 m (1 mm); with our ramp and Eq. 5.6 they do not (the '
    'integral too slow for the angle). The thesis does not say how that run started.',
    '- Minimum radius (Table 6.1: 0.50 m). The window centre is sqrt(r^2 + L_c^2) >= L_c = '
    '0.64 m from the centre of any circle the axle drives (r its radius), so on a 0.5 m tape it '
    'is at least 0.14 m off, beyond the 0.125 m half window: no law follows it with the window '
    "0.64 m ahead of the axle. Measured at the thesis's parking speed, 0.16 m/s: lost on R = "
    '0.5, 0.7 and 1.0 m with the preset; with the per-frame integral and P 2.5, R = 1.0 m is '
    'held (1 mm) and 0.7 m is lost.',
    '- The "0.024 m/s^2" acceleration (7.3, 7.6). As m/s^2 it would take 33 s to 0.79 m/s, '
    'against "less than 7 s even for 0.8 m/s" (7.3.2). Put through Eq. 6.12 as printed (the '
    'gear ratio twice), it is 0.112 m/s^2 at the rim: 7.0 s to 0.785 m/s on both models, as '
    'the text says. But the trapezoid also paces every change of wheel speed the steering '
    'asks for: the step overshoots 37 mm (kinematic) and 67 mm (dynamic) and the start takes '
    "10.5-10.7 s to come within 5 mm, against the thesis's 10 % and 3 s. The world's 0.3 "
    'm/s^2 stays; 0.112 is the option (world concic2.acceleration).',
    '- Image rows. All 64 rows against the 3 of the preset: 12.8 against 12.9 mm (kinematic), '
    "29.3 against 28.9 mm (dynamic), as the thesis's \"marginal improvement (less than 1 %)\" "
    'from 3 to 30 rows (7.2).',
    "- Servo time constant. 6.3.8 puts the cycle at a quarter of the servo loop's time "
    "constant; the cycle is 40-60 ms (6.3.10, 7.5.1.6): 0.16-0.24 s. The dynamic model's loop "
    'alone takes 0.198 s to 63 % (within); 0.242 s counts the 0.1 s the 0.3 m/s^2 trapezoid '
    'takes over the step itself.',
]


def table(experiments: list) -> list[str]:
    """Run each experiment on both models; return its rows (printed as they come)."""
    rows = []
    for name, run, extra, cells, *world in experiments:
        kw = world[0] if world else {}
        results = {vehicle: run(vehicle, *extra, **kw) for vehicle in VEHICLES}
        for k, (quantity, thesis_says, cell) in enumerate(cells):
            rows.append(f'| {name if k == 0 else ""} | {quantity} | {thesis_says} | '
                        f'{cell(results["kinematic"])} | {cell(results["dynamic"])} |')
            print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', type=Path, default=None, help='also write the tables here')
    args = ap.parse_args(argv)
    command = ('.venv/bin/python bench/concic2_thesis_bench.py '
               + ' '.join(sys.argv[1:] if argv is None else argv)).strip()
    figures = {vehicle: drive(vehicle) for vehicle in VEHICLES}
    drive_rows = [f'| {name} | {said} | {fmt(figures["kinematic"][key], digits)} | '
                  f'{fmt(figures["dynamic"][key], digits)} |'
                  for name, said, key, digits in DRIVE]
    print(*drive_rows, sep='\n', flush=True)
    head = ['| experiment | quantity | thesis | kinematic | dynamic |', '|---|---|---|---|---|']
    lines = ['# Thesis experiments on both CONCIC-II models', '', f'Command: `{command}`', '',
             ' '.join(__doc__.split('\n\n')[2].split()), '', '## The drive, open loop', '',
             ' '.join(drive.__doc__.split('\n\n')[1].split()), '',
             '| quantity | thesis | kinematic | dynamic |', '|---|---|---|---|', *drive_rows,
             '', '## The experiments with the thesis preset', '', *head,
             *table(EXPERIMENTS), '', '## The other readings, each alone against the preset',
             '', *head, *table(READINGS), '', *NOTES]
    text = '\n'.join(lines) + '\n'
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
