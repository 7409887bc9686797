"""Fleet benchmark: transfers per hour and the dispatcher's decision time, N trucks in lock step.

Each truck is a whole lock-step truck (world core and seven node cores) on demo_1983, driven by
the dispatcher through its VDA 5050 bridge core (agv_nodes.fleet.bridged). Two loads go round:
A between W0 and W2, B between W1 and W3; the next transfer of a load is submitted when its last
one is done, so every transfer is possible whatever the order the trucks finish in. The
trucks start at stop markers, W2.2, W0.1 and W1.1, told so by initPosition (the bridge sends
the truck the task `at N first|second`, so the truck at W1.1 leaves by L1's SRM). demo_1983
has room for three: four trucks (the fourth at W3.1) would hold all four of its blocks, and on
the one-way loop none could enter the next (test_fleet_bridged.py shows the watchdog report
that deadlock); W2.1 is 1.2 m from W2.2, closer than a truck's length.

Run: .venv/bin/python bench/fleet_bench.py [--seconds 900] [--trucks 1 2 3]
Prints a Markdown table (bench/results/fleet_bench.md).
"""

from __future__ import annotations

import argparse
import statistics
import time

from agv_nodes.fleet.bridged import BridgedFleet
from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.world.layout import layout_path, load_layout

POSITIONS = ('W2.2', 'W0.1', 'W1.1')  # where trucks 1, 2 and 3 are set down
LOADS = {'A': ('W0', 'W2'), 'B': ('W1', 'W3')}  # each load's two stations, where it starts first


class TimedDispatcher(Dispatcher):
    """The dispatcher, its step timed."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)
        self.decisions: list[float] = []

    def step(self, now: float) -> list:
        t0 = time.perf_counter()
        out = super().step(now)
        self.decisions.append(time.perf_counter() - t0)
        return out


def run(trucks: int, seconds: float) -> dict[str, float]:
    """Run `trucks` trucks for `seconds` of simulated time; return the figures."""
    lay = load_layout(layout_path('demo_1983'))
    at = {m.name: (m.path, m.at) for m in lay.markers}
    names = [f'agv{k + 1}' for k in range(trucks)]
    positions = dict(zip(names, POSITIONS, strict=False))
    fleet = Fleet('demo_1983', [at[positions[n]] for n in names])
    d = TimedDispatcher(track_graph(lay), names, positions=positions)
    where = {load: 0 for load in LOADS}  # index of the station the load is at
    pending: dict[str, str] = {}  # transfer id -> load
    serial = 0

    def submit(load: str) -> None:
        nonlocal serial
        serial += 1
        here = LOADS[load][where[load]]
        there = LOADS[load][1 - where[load]]
        pending[f't{serial}'] = load
        d.submit(TransportOrder(f't{serial}', here, there))

    for load in LOADS:
        submit(load)
    bridged = BridgedFleet(fleet, d, graph=d.graph)
    wall = time.perf_counter()
    done = 0

    def follow() -> bool:
        nonlocal done
        while done < len(d.done):
            load = pending.pop(d.done[done])
            where[load] = 1 - where[load]
            done += 1
            submit(load)
        return bool(d.failed or fleet.collisions)

    stopped = bridged.run(seconds, until=follow)
    wall = time.perf_counter() - wall
    if stopped:
        raise SystemExit(f'{trucks} trucks: failed {d.failed}, collisions {fleet.collisions}')
    ms = sorted(1000 * s for s in d.decisions)
    return {'trucks': trucks, 'transfers': done, 'per_hour': done * 3600 / seconds,
            'median_ms': statistics.median(ms), 'p99_ms': ms[int(0.99 * (len(ms) - 1))],
            'max_ms': ms[-1], 'factor': seconds / wall, 'collisions': len(fleet.collisions),
            'deadlocks': len(d.deadlocks)}


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seconds', type=float, default=900.0, help='simulated s per fleet size')
    ap.add_argument('--trucks', type=int, nargs='+', default=[1, 2, 3],
                    choices=range(1, len(POSITIONS) + 1))
    args = ap.parse_args()
    print(f'Fleet in lock step on demo_1983, {args.seconds:g} s simulated per row; loads A '
          '(W0 <-> W2) and B (W1 <-> W3) going round; `bench/fleet_bench.py`.\n')
    print('| trucks | transfers | per hour | decision median ms | p99 ms | max ms | '
          'real-time factor | collisions |')
    print('|---|---|---|---|---|---|---|---|')
    for n in args.trucks:
        r = run(n, args.seconds)
        print(f'| {n} | {r["transfers"]} | {r["per_hour"]:.0f} | {r["median_ms"]:.2f} | '
              f'{r["p99_ms"]:.2f} | {r["max_ms"]:.2f} | {r["factor"]:.1f} | '
              f'{r["collisions"]} |', flush=True)


if __name__ == '__main__':
    main()
