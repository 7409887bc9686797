"""Fleet benchmark in lock step: transfers per hour, decision time, where the time goes.

Each truck is a whole lock-step truck (world core and seven node cores), driven by the
dispatcher through its VDA 5050 bridge core (agv_nodes.fleet.bridged). A row is a layout and a
fleet size N:

- demo_1983, N = 1-3: the trucks start at its `parking` stop markers W2.2, W0.1 and W1.1; two
  loads go round, A between W0 and W2, B between W1 and W3. Four trucks would hold all four
  blocks of its one-way loop and none could move (test_fleet_bridged.py).
- fleet_1983 (config/layouts), N = 1, 2, 4, 8, and floors written by
  agv_nodes.world.fleet_floor for larger N (fleet_1983_n16, fleet_1983_n32: the room lengthened
  by extension_for(N), to a temporary directory): house-numbered locations, the trucks at the
  first N `parking` places (every other A house, then B), one load per truck, load k between
  Ak and Bk.
- loops_1983 (config/layouts), N = 1, 2, 4, 5: the two-loop floor
  (agv_nodes.world.loops_floor), the trucks at its `parking` places, one load per truck, load k
  between Ak and Bk.

The loads are fleet_floor.programme_loads's: the next transfer of a load is submitted when its
last one is done, so every transfer is possible whatever order the trucks finish in. The
dispatcher gets the trucks' places as `positions` (told by initPosition) and `parking`, as the
launched fleet's dispatcher node does (agv_nodes.graph.parameters).

The wall time is split, per simulated second: the trucks' harness steps, the contact check
between them (the rest of Fleet.step), and the bridges with the dispatcher (the rest of
BridgedFleet.step). A pass is a `pass N` task a bridge sends for a node without action that
does not end the base: a house of the stop's identity the truck drives past (task_way); a
junction SRM is a `srm at N` task it sends where the way takes a junction (loops_1983), and a
re-routing is the watchdog's (agv_nodes.fleet.reroute).

Run: .venv/bin/python bench/fleet_bench.py [--seconds 900] [--big-seconds 600]
     [--rows demo_1983:1 fleet_1983:8 fleet_1983_n16:16 ...] [--processes 1 2]
`--processes P`: the trucks stepped in P processes (agv_nodes.fleet.truck_processes), the
same samples; then `trucks ms/s` is the first process's wall time stepping its own trucks and
waiting for the others'.
Prints a Markdown table (bench/results/fleet_bench.md). Fails (SystemExit) on a failed transfer
or a collision.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
import itertools
from pathlib import Path
import statistics
import tempfile
import time
from typing import Any

from agv_nodes.fleet.bridged import BridgedFleet
from agv_nodes.fleet.dispatcher import Dispatcher, TransportOrder
from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.world.fleet_floor import extension_for, fleet_floor_text, programme_loads
from agv_nodes.world.layout import layout_path, load_layout

ROWS = ('demo_1983:1', 'demo_1983:2', 'demo_1983:3', 'fleet_1983:1', 'fleet_1983:2',
        'fleet_1983:4', 'fleet_1983:8', 'fleet_1983_n16:16', 'fleet_1983_n32:32')
BIG = 16  # trucks from which a row runs --big-seconds
DEMO_POSITIONS = ('W2.2', 'W0.1', 'W1.1')  # demo_1983's places, as the earlier tables had them
DEMO_LOADS = {'A': ('W0', 'W2'), 'B': ('W1', 'W3')}


class TimedDispatcher(Dispatcher):
    """The dispatcher, its step timed and its wait cycles collected."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.decisions: list[float] = []
        self.cycles: set[frozenset[str]] = set()  # every wait cycle of standing trucks seen

    def step(self, now: float) -> list:
        t0 = time.perf_counter()
        out = super().step(now)
        self.decisions.append(time.perf_counter() - t0)
        self.cycles.update(frozenset(c) for c in self.deadlocks)
        return out


def timed(fn: Callable[[], Any], spent: dict[str, float], key: str) -> Callable[[], Any]:
    """Return `fn` that adds its wall seconds to spent[key]."""
    def wrapper() -> Any:
        t0 = time.perf_counter()
        out = fn()
        spent[key] += time.perf_counter() - t0
        return out
    return wrapper


def count_passes(flow: Any, counter: list[int]) -> None:
    """Count the passes (counter[0]) and junction SRMs (counter[1]) of the orders `flow` takes."""
    take = flow._take  # bench only: every accepted order's stop points pass here

    def wrapper(order: Any, points: list, verdict: str) -> Any:
        counter[0] += sum(1 for p in points if p.text.startswith('pass '))
        counter[1] += sum(1 for p in points if p.text.startswith('srm '))
        return take(order, points, verdict)
    flow._take = wrapper


def floor(name: str, trucks: int, tmp: Path) -> str:
    """Return the layout to load: `name` from config/layouts, else a fleet floor written to tmp."""
    if layout_path(name).exists():
        return name
    path = tmp / f'{name}.yaml'
    path.write_text(fleet_floor_text(name, extension_for(trucks), trucks))
    return str(path)


def run(name: str, trucks: int, seconds: float, tmp: Path, processes: int = 1
        ) -> dict[str, Any]:
    """Run `trucks` trucks on layout `name` for `seconds` of simulated time; return the figures."""
    layout = floor(name, trucks, tmp)
    lay = load_layout(layout_path(layout))
    if len(lay.parking) < trucks:
        raise SystemExit(f'{name}: {len(lay.parking)} parking places for {trucks} trucks')
    at = {m.name: (m.path, m.at) for m in lay.markers}
    names = [f'agv{k + 1}' for k in range(trucks)]
    places = dict(zip(names, lay.parking[:trucks], strict=True))
    loads = programme_loads(lay.stations, trucks)
    if name == 'demo_1983' and (lay.parking[:3] != DEMO_POSITIONS or loads != DEMO_LOADS):
        raise SystemExit(f'demo_1983 changed: parking {lay.parking}, loads {loads}')
    fleet = Fleet(layout, [at[places[n]] for n in names], processes=processes)
    d = TimedDispatcher(track_graph(lay), names, positions=places, parking=places)
    where = {load: 0 for load in loads}  # index of the station the load is at
    pending: dict[str, str] = {}  # transfer id -> load
    serial = 0

    def submit(load: str) -> None:
        nonlocal serial
        serial += 1
        pending[f't{serial}'] = load
        d.submit(TransportOrder(f't{serial}', loads[load][where[load]],
                                loads[load][1 - where[load]]))

    for load in loads:
        submit(load)
    bridged = BridgedFleet(fleet, d, graph=d.graph)
    passes = [0, 0]
    for bridge in bridged.bridges.values():
        count_passes(bridge.flow, passes)
    spent = dict.fromkeys(('trucks', 'contact', 'all'), 0.0)
    fleet.step_trucks = timed(fleet.step_trucks, spent, 'trucks')
    fleet.check_contacts = timed(fleet.check_contacts, spent, 'contact')
    bridged.step = timed(bridged.step, spent, 'all')
    done = 0

    def follow() -> bool:
        nonlocal done
        while done < len(d.done):
            load = pending.pop(d.done[done])
            where[load] = 1 - where[load]
            done += 1
            submit(load)
        return bool(d.failed or fleet.collisions)

    wall = time.perf_counter()
    with fleet:
        stopped = bridged.run(seconds, until=follow)
    wall = time.perf_counter() - wall
    if stopped:
        raise SystemExit(f'{name}, {trucks} trucks at {fleet.now:.1f} s: failed {d.failed}, '
                         f'collisions {fleet.collisions}')
    ms = sorted(1000 * s for s in d.decisions)
    per_s = 1000 / seconds  # wall s -> wall ms per simulated s
    return {'layout': name, 'trucks': trucks, 'blocks': len(d.reservations.blocks),
            'seconds': seconds, 'transfers': done, 'per_hour': done * 3600 / seconds,
            'passes': f'{passes[0] / done:.2f}' if done else '-',
            'median_ms': statistics.median(ms), 'p99_ms': ms[int(0.99 * (len(ms) - 1))],
            'max_ms': ms[-1], 'factor': seconds / wall,
            'trucks_ms': spent['trucks'] * per_s,
            'contact_ms': spent['contact'] * per_s,
            'master_ms': (spent['all'] - spent['trucks'] - spent['contact']) * per_s,
            'collisions': len(fleet.collisions), 'deadlocks': len(d.cycles),
            'srms': f'{passes[1] / done:.2f}' if done else '-', 'reroutes': len(d.reroutes)}


def row(spec: str) -> tuple[str, int]:
    """Parse a row `LAYOUT:N`."""
    name, _, n = spec.rpartition(':')
    if not name or not n.isdigit() or int(n) < 1:
        raise argparse.ArgumentTypeError(f'{spec!r}: a row is LAYOUT:N, e.g. fleet_1983:8')
    return name, int(n)


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seconds', type=float, default=900.0, help='simulated s per row')
    ap.add_argument('--big-seconds', type=float, default=600.0,
                    help=f'simulated s per row of {BIG} trucks or more')
    ap.add_argument('--rows', type=row, nargs='+', default=[row(r) for r in ROWS],
                    metavar='LAYOUT:N', help='layout (config/layouts, or a fleet floor '
                    'written for N, e.g. fleet_1983_n16) and trucks; default: '
                    + ' '.join(ROWS))
    ap.add_argument('--processes', type=int, nargs='+', default=[1], metavar='P',
                    help='run each row with the trucks stepped in P processes '
                    '(agv_nodes.fleet.truck_processes), once per value; default 1')
    args = ap.parse_args()
    print(f'Fleet in lock step, {args.seconds:g} s simulated per row ({args.big_seconds:g} s '
          f'from {BIG} trucks); `bench/fleet_bench.py`. Time split: wall ms per simulated s.\n')
    columns = ('layout', 'trucks', 'processes', 'blocks', 'sim s', 'transfers', 'per hour',
               'per truck-hour', 'passes / transfer', 'decision median ms', 'p99 ms', 'max ms',
               'real-time factor', 'trucks ms/s', 'contact ms/s', 'bridges+dispatcher ms/s',
               'collisions', 'deadlocks', 'junction SRMs / transfer', 're-routings')
    print('| ' + ' | '.join(columns) + ' |')
    print('|' + '---|' * len(columns))
    with tempfile.TemporaryDirectory() as tmp:
        for (name, n), p in itertools.product(args.rows, args.processes):
            r = run(name, n, args.big_seconds if n >= BIG else args.seconds, Path(tmp), p)
            cells = (name, n, p, r['blocks'], f'{r["seconds"]:g}', r['transfers'],
                     f'{r["per_hour"]:.0f}', f'{r["per_hour"] / n:.1f}', r['passes'],
                     f'{r["median_ms"]:.2f}', f'{r["p99_ms"]:.2f}', f'{r["max_ms"]:.2f}',
                     f'{r["factor"]:.2f}', f'{r["trucks_ms"]:.1f}', f'{r["contact_ms"]:.1f}',
                     f'{r["master_ms"]:.1f}', r['collisions'], r['deadlocks'], r['srms'],
                     r['reroutes'])
            print('| ' + ' | '.join(map(str, cells)) + ' |', flush=True)

if __name__ == '__main__':
    main()
