"""Fleet benchmark over DDS and MQTT: `agv-demo --fleet N` for each N, one table.

Each row is one run of the fleet demonstration (agv_nodes.fleet.fleet_demo): N trucks on the
layout (--layout: demo_1983, room for three, or fleet_1983, eight), each truck's graph its own
processes, one world process for the floor, the dispatcher as the VDA 5050 master of every
truck's bridge over the embedded MQTT broker. By default the world runs as fast as the
slowest node keeps up (time factor 0), so the real-time factor is what the 2-core machine gives
N trucks; `--time-factor F` holds it to F instead, for a fleet whose processes would otherwise
starve each other. Transfers per hour are per simulated hour.

Run: .venv/bin/python bench/fleet_dds_bench.py [--layout demo_1983] [--trucks 1 2]
     [--transfers 4] [--time-factor 0]
Prints a Markdown table (bench/results/fleet_dds_bench.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile


def run(trucks: int, transfers: int, out: Path, layout: str = 'demo_1983',
        time_factor: float = 0.0) -> dict:
    """Run the demo for `trucks` trucks on `layout`; return its fleet.json."""
    demo = Path(sys.executable).parent / 'agv-demo'
    res = subprocess.run([str(demo), '--fleet', str(trucks), '--layout', layout,
                          '--transfers', str(transfers), '--time-factor', str(time_factor),
                          '--no-report', '--out', str(out)],
                         capture_output=True, text=True, timeout=7200)
    if res.returncode != 0:
        keep = Path(tempfile.mkdtemp(prefix=f'fleet_dds_bench_{trucks}_'))
        shutil.copytree(out, keep, dirs_exist_ok=True)  # the logs and bag, to find out why
        raise SystemExit(f'{trucks} trucks: agv-demo failed (its logs and bag kept in {keep})'
                         f'\n{res.stdout[-3000:]}{res.stderr[-3000:]}')
    return json.loads((out / 'fleet.json').read_text())


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--layout', default='demo_1983', help='the floor, passed to agv-demo')
    ap.add_argument('--trucks', type=int, nargs='+', default=[1, 2])
    ap.add_argument('--transfers', type=int, default=4, help='transfers per run')
    ap.add_argument('--time-factor', type=float, default=0.0,
                    help='simulated s per real s the world aims for (0: as fast as the '
                    'slowest node keeps up)')
    args = ap.parse_args()
    pace, flag = (f'time factor {args.time_factor:g}', f' --time-factor {args.time_factor:g}') \
        if args.time_factor else ('time factor 0 (as fast as the slowest node keeps up)', '')
    print(f'Fleet over DDS and MQTT on {args.layout}, {args.transfers} transfers per row, '
          f'{pace}; `bench/fleet_dds_bench.py --layout {args.layout} '
          f'--trucks {" ".join(map(str, args.trucks))} --transfers {args.transfers}{flag}`.\n')
    print('| trucks | processes | transfers | simulated s | per simulated hour | real-time '
          'factor | wall s | dispatcher step median ms | p99 ms | max ms | collisions |\n'
          '|---|---|---|---|---|---|---|---|---|---|---|')
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.trucks:
            r = run(n, args.transfers, Path(tmp) / f'fleet{n}', args.layout, args.time_factor)
            steps = r['dispatcher']
            done = len(r['done'])
            print(f'| {n} | {r["processes"]} | {done} | {r["sim_seconds"]:.0f} | '
                  f'{done * 3600 / r["sim_seconds"]:.0f} | {r["real_time_factor"]:.2f} | '
                  f'{r["wall_seconds"]:.0f} | {steps.get("step median ms", "-")} | '
                  f'{steps.get("step p99 ms", "-")} | {steps.get("step max ms", "-")} | '
                  f'{r["collisions"]} |', flush=True)


if __name__ == '__main__':
    main()
