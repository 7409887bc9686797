"""Stop-accuracy benchmark: repeated stops at a stop marker, both stopping modes.

Each run is a fresh truck on straight_track (seeded; start position varied), told "stop at 1
first": it cruises at the given demand, navigation slows it at location 1 and stops it at its
stop marker 1.0 m on. The ground-truth stop error (sensor axis past the marker centre) comes
from the world. Thesis 7.2: +-4 cm about the mean with friction stopping; the goal for
`controlled` (closed-loop traction): +-5 mm (3 sigma) and |bias| < 5 mm.

Run: .venv/bin/python bench/stop_bench.py [--runs 30] [--csv bench/results/stops.csv]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
import statistics
import sys

from agv_nodes.harness import submit, truck

SPEEDS = {0.7: 55, 1.0: 80}  # m/s -> cruise demand (% duty)


def one_stop(seed: int, demand: int, payload: float, mode: str,
             trace: list[str] | None = None, link_reaction: str = 'at_once') -> dict:
    """Run one stop; return the stop error (mm) and the speed at the location marker.

    With `trace`, every change of navigation's view or link while positioning is appended to it
    with the ground truth (sensor axis past the centre, mm) and the truck's speed.
    """
    controlled = mode == 'controlled'
    h = truck('straight_track', seed=seed, overrides={
        'world': {'electruk.payload': payload},
        'traction': {'control': 'closed_loop' if controlled else 'open_loop_1983',
                     'link_reaction': link_reaction},
        'navigation': {'stopping': 'controlled' if controlled else 'friction_1983'},
        'executive': {'cruise_demand': demand}})
    # Vary where the truck starts so the sampling phase at the markers varies run to run.
    h.world.vehicle.state.x -= (seed % 17) * 0.013
    submit(h, 'stop at 1 first')
    ex, nav = h.cores['executive'], h.cores['navigation']
    last = None
    while h.now < 120 and (ex.mode == 'running' or h.cores['communications'].queue):
        h.step()
        if trace is None or nav.mode != 'positioning':
            continue
        link = nav.link
        key = (nav.stop_view, link['reverse'], link['speed'], link['stop_in'])
        if key != last:
            last = key
            _marker, along = h.world.truth.nearest_stop_marker()
            trace.append(f'{h.now:7.3f} s  view {nav.stop_view}  link reverse {link["reverse"]} '
                         f'speed {link["speed"]:2d} stop_in {link["stop_in"]:3d}  truth '
                         f'{along * 1000:+6.1f} mm  v {h.world.vehicle.state.speed:+.3f} m/s')
    stops = [e for e in h.events if e['event'] == 'stopped' and e['marker'] == 'S1.1']
    at_marker = [e for e in h.events if e['event'] == 'marker_passed' and e['marker'] == 'L1']
    return {'seed': seed, 'mode': mode, 'payload': payload, 'demand': demand,
            'ok': ex.mode == 'idle' and bool(stops),
            'error_mm': stops[-1]['error'] if stops else None,
            'speed_at_location': at_marker[0]['speed'] if at_marker else None,
            'sim_s': h.now}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--runs', type=int, default=30)
    ap.add_argument('--csv', type=Path, default=Path('bench/results/stops.csv'))
    ap.add_argument('--modes', default='friction_1983,controlled')
    ap.add_argument('--trace', default='', help='SEEDS:SPEED:PAYLOAD (e.g. 1,3:1.0:1000): '
                    'print the positioning of these runs (controlled) instead of the tables')
    ap.add_argument('--link-reaction', default='at_once', choices=('at_once', 'loop'),
                    help="traction's link_reaction (agv_nodes/traction/core.py)")
    args = ap.parse_args()
    if args.trace:
        seeds, speed, payload = args.trace.split(':')
        for seed in (int(x) for x in seeds.split(',')):
            lines: list[str] = []
            run = one_stop(seed, SPEEDS[float(speed)], float(payload), 'controlled', lines,
                           args.link_reaction)
            print(f'seed {seed}: stop error {run["error_mm"]} mm')
            print('\n'.join(f'  {line}' for line in lines))
        return 0
    rows = []
    print('| mode | speed (m/s) | payload (kg) | runs ok | mean error (mm) | sd (mm) | '
          '3 sd (mm) | min..max (mm) |')
    print('|---|---|---|---|---|---|---|---|')
    for mode in args.modes.split(','):
        for speed, demand in SPEEDS.items():
            for payload in (0.0, 1000.0):
                results = [one_stop(seed, demand, payload, mode, link_reaction=args.link_reaction)
                           for seed in range(args.runs)]
                rows += results
                errors = [r['error_mm'] for r in results if r['ok']]
                if not errors:
                    print(f'| {mode} | {speed} | {payload:.0f} | 0/{len(results)} | '
                          '- | - | - | - |')
                    continue
                mean = statistics.fmean(errors)
                sd = statistics.pstdev(errors)
                print(f'| {mode} | {speed} | {payload:.0f} | {len(errors)}/{len(results)} | '
                      f'{mean:+.1f} | {sd:.1f} | {3 * sd:.1f} | {min(errors)}..{max(errors)} |',
                      flush=True)
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with args.csv.open('w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f'\nper-run results: {args.csv}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
