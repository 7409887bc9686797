"""Recognition benchmark on the belt rig of thesis 7.1.1.

The six test patterns (locations 0-3, the stop marker, all white) pass the sensor on a belt at a
set speed, standoff, height and angle; the world's photodiode model makes the ADC snapshots and
the position sensor core recognises them with the navigating table. Per pattern and setting:
the fraction of passes recognised correctly, the mean number of matching snapshots per pass
(thesis fig 7.11 counts matches), and misreads (a recognition of anything else). The misread
study compares min_consecutive_matches 1 and 2 with detector skew (+-1 sample, thesis 7.1.3) and
extra noise. Goals: 100 % recognition to 2 m/s; 0 misreads in 10,000 passes within
300 +- 20 mm and +-10 mm height.

The position sensor's `decoder` is compared too: `snapshot` (the thesis rule, one snapshot with
every detector decided) and `sequence` (the default: each column reads the card in time).

Run: .venv/bin/python bench/recognition_bench.py [--passes 20] [--misread-passes 2000]
     [--misread-only 4:1.0:2,2:1.0:2:invalid:sequence]  (the misread study alone;
     1,670 x 6 patterns = 10,020)
"""

from __future__ import annotations

import argparse
import math
import random
import sys

from agv_nodes.markers import EDIM
from agv_nodes.position_sensor.core import PositionSensorCore
from agv_nodes.position_sensor.settings import SensorProcessing
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.marker_sensor import MarkerSensorModel
from agv_nodes.world.settings import SensorParams, WorldParams

EXPECTED = {'L0': 0, 'L1': 1, 'L2': 2, 'L3': 3, 'S.1': EDIM, 'W': None}


def run_belt(speed: float, standoff: float = 0.300, height: float = 0.0, angle: float = 0.0,
             passes: int = 10, seed: int = 1, consecutive: int = 2, skew_mm: float = 0.0,
             noise: float = 1.0, run_length: int = 4, band: str = 'invalid',
             misses: list[str] | None = None,
             decoder: str = 'snapshot') -> dict[str, dict[str, float]]:
    """Run passes of the six patterns; per pattern: recognised fraction, matches, misreads.

    With `misses`, each missed pass is appended to it with one character per snapshot while
    the card is in front of the lens: '.' invalid, '-' a code of no template, else the template
    matched (E = the stop-marker centre), '*' after a match some detector held.
    """
    lay = _rig_layout(speed, standoff, height, angle)
    rng = random.Random(seed)
    skew = tuple(rng.uniform(-skew_mm, skew_mm) / 1000 for _ in range(8))
    stats = {name: {'passes': 0, 'recognised': 0, 'matches': 0, 'misreads': 0}
             for name in EXPECTED}
    for k in range(passes):
        params = WorldParams(seed=seed * 1000 + k, sample_rate=340.0,
                             sensor=SensorParams(noise=noise, skew=skew))
        world = WorldCore(lay, params)
        world._rig_s = rng.uniform(0.0, 0.02)  # a different sampling phase every pass
        sensor = PositionSensorCore(SensorProcessing(min_consecutive_matches=consecutive,
                                                     run_length=run_length,
                                                     invalid_band=band, decoder=decoder))
        seen: dict[str, set] = {n: set() for n in EXPECTED}
        marks: dict[str, list[str]] = {n: [] for n in EXPECTED}
        while not world.done_rig():
            adc = world.step()['records']['adc_snapshot']
            before = sensor._streak
            got = sensor.sample([adc[f'lit_{d}'] for d in range(1, 9)],
                                [adc[f'dark_{d}'] for d in range(1, 9)], world.time)
            near = _nearest(world, lay)
            if near is None:
                continue
            if sensor._streak > before:
                stats[near]['matches'] += 1
            if got:
                seen[near].add(got['position_sensor_status']['identity'])
            if misses is not None:
                marks[near].append(_mark(sensor))
        for name, ids in seen.items():
            stats[name]['passes'] += 1
            want = EXPECTED[name]
            found = want is None or want in ids
            stats[name]['recognised'] += int(found)
            stats[name]['misreads'] += len(ids - {want})
            if misses is not None and not found:
                misses.append(f'standoff {standoff * 1000:.0f} mm, height '
                              f'{height * 1000:+.1f} mm, {name} missed: {"".join(marks[name])}')
    return stats


def _mark(sensor: PositionSensorCore) -> str:
    """One snapshot for run_belt's `misses`."""
    if sensor.invalid:
        return '.'
    match = sensor._templates.get(sensor.code)
    if match is None:
        return '-'
    return ('E' if match == EDIM else str(match)) + ('' if sensor._streak_decisive else '*')


def study_geometry(groups: int):
    """Draw the misread study's random geometry: (group, standoff, height) per 10 passes."""
    rng = random.Random(7)
    for k in range(groups):
        yield k, rng.uniform(0.28, 0.32), rng.uniform(-0.01, 0.01)


def study_group(k: int, standoff: float, height: float, speed: float, run_length: int,
                consecutive: int = 2, band: str = 'invalid', misses: list[str] | None = None,
                decoder: str = 'snapshot') -> dict[str, dict[str, float]]:
    """Ten passes of each pattern of the misread study (skew +-3 mm, noise 2 counts)."""
    return run_belt(speed, standoff=standoff, height=height, passes=10, seed=100 + k,
                    consecutive=consecutive, skew_mm=3.0, noise=2.0, run_length=run_length,
                    band=band, misses=misses, decoder=decoder)


def show_misses(groups: int, speed: float, run_length: int, band: str,
                decoder: str = 'snapshot') -> None:
    """Each missed pass of `groups` x 10 passes of the misread study (run_belt's `misses`)."""
    for k, standoff, height in study_geometry(groups):
        lines: list[str] = []
        study_group(k, standoff, height, speed, run_length, band=band, misses=lines,
                    decoder=decoder)
        for line in lines:
            print(line, flush=True)


MOTIONS = {
    'stop': 'brakes (0.3-2 m/s^2) to rest within 0.1 m of the card centre, waits 0-1 s, goes on',
    'reverse': 'passes, stops up to 0.15 m beyond, backs over it at 0.05-0.3 m/s, goes on',
    'jerky': 'a new speed in 0-1.5 m/s at random, every 50 snapshots on average',
}


def lens_track(kind: str, rng: random.Random, centre: float, dt: float = 1 / 340):
    """Return lens positions along the belt, one per snapshot, for a truck moving past a card.

    The truck moves as MOTIONS[kind] says past a card at `centre` from 0.4 m before it to 0.4 m
    after (cruise 0.3-1.2 m/s).
    """
    v0, acc, s = rng.uniform(0.3, 1.2), rng.uniform(0.3, 2.0), centre - 0.4
    if kind == 'stop':
        stop_at, v = centre + rng.uniform(-0.1, 0.1), v0
        while s < stop_at - v0 * v0 / (2 * acc):
            s += v * dt
            yield s
        while v > 0:
            v = max(0.0, v - acc * dt)
            s += v * dt
            yield s
        for _ in range(int(rng.uniform(0.0, 1.0) / dt)):
            yield s
        while s < centre + 0.4:
            v = min(v0, v + acc * dt)
            s += v * dt
            yield s
    elif kind == 'reverse':
        beyond, back = centre + rng.uniform(0.0, 0.15), rng.uniform(0.05, 0.3)
        target = centre - rng.uniform(0.0, 0.15)
        while s < beyond:
            s += v0 * dt
            yield s
        while s > target:
            s -= back * dt
            yield s
        while s < centre + 0.4:
            s += v0 * dt
            yield s
    else:
        v = v0
        while s < centre + 0.4:
            if rng.random() < 0.02:
                v = rng.uniform(0.0, 1.5)
            s += v * dt
            yield s


def motion_study(trials: int, decoders: tuple[str, ...] = ('snapshot', 'sequence')) -> None:
    """Study cards met while the truck stops, reverses or changes speed over them.

    Each trial draws a standoff (280-320 mm), height (+-10 mm), detector skew (+-3 mm) and one
    track per card; every decoder sees the same snapshots.
    """
    print(f'\nCards met at changing speed ({trials} trials x 6 patterns per motion; noise 2 '
          'counts)\n')
    print('| motion | decoder | cards | recognised | misreads |\n|---|---|---|---|---|')
    for kind in MOTIONS:
        rng = random.Random(11)
        right = {d: 0 for d in decoders}
        wrong = {d: 0 for d in decoders}
        for t in range(trials):
            lay = _rig_layout(1.0, rng.uniform(0.28, 0.32), rng.uniform(-0.01, 0.01), 0.0)
            skew = tuple(rng.uniform(-0.003, 0.003) for _ in range(8))
            model = MarkerSensorModel(SensorParams(noise=2.0, skew=skew), random.Random(t))
            for m in lay.markers:
                cores = {d: PositionSensorCore(SensorProcessing(decoder=d)) for d in decoders}
                seen: dict[str, set] = {d: set() for d in decoders}
                for k, s in enumerate(lens_track(kind, rng, m.at)):
                    lit, dark = model.snapshot((s, 0.0), 0.0, [m], 0.0)
                    for d, core in cores.items():
                        out = core.sample(lit, dark, k / 340)
                        if out:
                            seen[d].add(out['position_sensor_status']['identity'])
                want = EXPECTED[m.name]
                for d in decoders:
                    right[d] += want is None or want in seen[d]
                    wrong[d] += len(seen[d] - {want})
        for d in decoders:
            print(f'| {kind} | {d} | {6 * trials} | {right[d]} | {wrong[d]} |', flush=True)


def _rig_layout(speed: float, standoff: float, height: float, angle: float):
    """sensor_rig with every card at the given standoff, height and angle."""
    lay = load_layout(layout_path('sensor_rig'))
    lay.rig.update(speed=speed)
    path = lay.paths['belt']
    for m in lay.markers:
        m.standoff, m.height, m.yaw = standoff, height, math.radians(angle)
        x, y, h = path.pose_at(m.at)
        m.centre = (x + math.sin(h) * standoff, y - math.cos(h) * standoff)
        m.normal = (-math.sin(h + m.yaw), math.cos(h + m.yaw))
        m.along = (math.cos(h + m.yaw), math.sin(h + m.yaw))
    return lay


def _nearest(world: WorldCore, lay) -> str | None:
    """Return the card in front of the lens (within half a card), by name."""
    (lx, _ly), _h = world.lens_pose()
    for m in lay.markers:
        if abs(m.centre[0] - lx) < 0.12:
            return m.name
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--passes', type=int, default=10)
    ap.add_argument('--misread-passes', type=int, default=200)
    ap.add_argument('--misread-only', default='', help='only the misread study, for these '
                    'RUN_LENGTH:SPEED:MIN_CONSECUTIVE[:BAND[:DECODER]] configurations, comma '
                    'separated (BAND: invalid, the thesis, or hold; DECODER: snapshot, the '
                    'thesis, or sequence)')
    ap.add_argument('--show-misses', default='', help='GROUPS:SPEED:RUN_LENGTH[:BAND[:DECODER]]: '
                    'print the snapshots of every missed pass of GROUPS x 10 passes per '
                    'pattern of the misread study')
    ap.add_argument('--motion', type=int, default=0, metavar='TRIALS',
                    help='only the changing-speed study (stop, reverse, jerky), TRIALS x 6 '
                    'cards per motion')
    args = ap.parse_args()
    if args.motion:
        motion_study(args.motion)
        return 0
    if args.show_misses:
        groups, speed, run_length, *rest = args.show_misses.split(':')
        rest += ['invalid', 'snapshot'][len(rest):]
        show_misses(int(groups), float(speed), int(run_length), rest[0], rest[1])
        return 0
    configs = [(4, 1.0, 1, 'invalid', 'snapshot'), (4, 1.0, 2, 'invalid', 'snapshot'),
               (2, 1.0, 1, 'invalid', 'snapshot'), (2, 1.0, 2, 'invalid', 'snapshot'),
               (2, 2.0, 2, 'invalid', 'snapshot'), (4, 1.0, 2, 'hold', 'snapshot'),
               (2, 2.0, 2, 'hold', 'snapshot'), (4, 1.0, 2, 'invalid', 'sequence'),
               (4, 2.0, 2, 'invalid', 'sequence')]
    if args.misread_only:
        configs = []
        for item in args.misread_only.split(','):
            n, v, c, *rest = item.split(':')
            rest += ['invalid', 'snapshot'][len(rest):]
            configs.append((int(n), float(v), int(c), rest[0], rest[1]))
        misreads(args.misread_passes, configs)
        return 0
    names = list(EXPECTED)
    for decoder, run_length in (('snapshot', 4), ('snapshot', 2), ('sequence', 4)):
        print(f'Recognised passes (%) by speed (decoder {decoder}, run_length {run_length}, '
              'standoff 300 mm, height 0, angle 0)\n')
        print('| speed (m/s) | ' + ' | '.join(names) + ' | mean matches/pass (L0..L3) |')
        print('|---' * (len(names) + 2) + '|')
        for speed in (0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0):
            st = run_belt(speed, passes=args.passes, run_length=run_length, decoder=decoder)
            cells = [f'{100 * st[n]["recognised"] / st[n]["passes"]:.0f}' for n in names]
            matches = [st[n]['matches'] / st[n]['passes'] for n in ('L0', 'L1', 'L2', 'L3')]
            shown = ('-' if decoder == 'sequence'  # it matches no snapshot in navigating
                     else ', '.join(f'{m:.1f}' for m in matches))
            print(f'| {speed} | ' + ' | '.join(cells) + f' | {shown} |', flush=True)
        print()
    print('\nRecognised passes (%) at 1 m/s by standoff, height and angle (run_length 4)\n')
    print('| setting | decoder | ' + ' | '.join(names) + ' |')
    print('|---' * (len(names) + 2) + '|')
    settings = [('standoff 260 mm', dict(standoff=0.260)), ('standoff 280 mm',
                dict(standoff=0.280)), ('standoff 320 mm', dict(standoff=0.320)),
                ('standoff 340 mm', dict(standoff=0.340)), ('height +10 mm', dict(height=0.010)),
                ('height -10 mm', dict(height=-0.010)), ('angle +10 deg', dict(angle=10.0)),
                ('angle -10 deg', dict(angle=-10.0)), ('angle +15 deg', dict(angle=15.0)),
                ('angle -15 deg', dict(angle=-15.0))]
    for (label, kw), decoder in ((setting, dec) for setting in settings
                                 for dec in ('snapshot', 'sequence')):
        st = run_belt(1.0, passes=args.passes, decoder=decoder, **kw)
        print(f'| {label} | {decoder} | ' + ' | '.join(
            f'{100 * st[n]["recognised"] / st[n]["passes"]:.0f}' for n in names) + ' |',
            flush=True)
    misreads(args.misread_passes, configs)
    motion_study(max(1, args.passes * 5))
    return 0


def misreads(passes: int, configs: list[tuple[int, float, int, str, str]]) -> None:
    """Run the misread study: passes of each pattern per configuration."""
    names = list(EXPECTED)
    print(f'\nMisreads in {passes} passes of each pattern (random standoff '
          '280-320 mm and height +-10 mm per pass, detector skew +-3 mm, noise 2 counts)\n')
    print('| decoder | run_length | speed (m/s) | min_consecutive_matches | invalid_band | '
          'passes | misreads | missed |')
    print('|---|---|---|---|---|---|---|---|')
    for run_length, speed, consecutive, band, decoder in configs:
        wrong = missed = total = 0
        for k, standoff, height in study_geometry(passes // 10):
            st = study_group(k, standoff, height, speed, run_length, consecutive, band,
                             decoder=decoder)
            for n in names:
                total += st[n]['passes']
                wrong += st[n]['misreads']
                missed += st[n]['passes'] - st[n]['recognised']
        print(f'| {decoder} | {run_length} | {speed} | {consecutive} | {band} | {total} | '
              f'{wrong} | {missed} |', flush=True)


if __name__ == '__main__':
    sys.exit(main())
