"""Start-up benchmark: how long the launched graph takes to move, and each process's CPU till then.

Launches the demo graph (agv-launch's nine processes less the recorder, sim time, time factor 0,
as the DDS tests launch it) `--rounds` times and notes, per round, the wall time from the launch
to the world's first step (its ready file) and each node process's CPU by then. Every DDS test
pays this once per graph it starts. The package the node processes import is the one on
PYTHONPATH, so the same file measures another tree: `PYTHONPATH=/other/tree`.

Run: .venv/bin/python bench/startup_bench.py [--rounds 5]
Prints a Markdown table (bench/results/test_suite.md).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import statistics
import sys
import tempfile
import time

from agv_nodes.discovery import use_localhost_discovery
from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch


def one_start(domain: int) -> tuple[float, dict[str, float]]:
    """Launch the graph; return (s until the world moves, {process: CPU s by then})."""
    with tempfile.TemporaryDirectory() as tmp:
        launch = Launch(Options(time_factor=0.0, quiet=True, domain_id=domain,
                                log_dir=Path(tmp) / 'logs'))
        t0 = time.monotonic()
        launch.start()
        try:
            while not launch.moving.is_set():
                if failed := launch.poll():
                    raise SystemExit(f'startup_bench: {failed} exited during start-up')
                if time.monotonic() - t0 > 120:
                    raise SystemExit('startup_bench: the world did not move within 120 s')
                time.sleep(0.01)
            return time.monotonic() - t0, launch.cpu_seconds()
        finally:
            launch.stop()


def main() -> int:
    """Measure `--rounds` starts; print the medians."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rounds', type=int, default=5)
    ap.add_argument('--domain-id', type=int, default=int(os.environ.get('ROS_DOMAIN_ID', '173')))
    args = ap.parse_args()
    use_localhost_discovery()
    starts = [one_start(args.domain_id) for _ in range(args.rounds)]
    moving = statistics.median(s for s, _cpu in starts)
    names = sorted(starts[0][1], key=lambda n: -starts[0][1][n])
    print(f'| start-up, median of {args.rounds} (package from '
          f'{os.environ.get("PYTHONPATH", "the install")}) | value |')
    print('|---|---|')
    print(f'| launch to the world moving (s) | {moving:.2f} |')
    print(f'| CPU of all processes by then (s) | '
          f'{statistics.median(sum(cpu.values()) for _s, cpu in starts):.2f} |')
    for name in names:
        print(f'| CPU of {name} (s) | {statistics.median(cpu[name] for _s, cpu in starts):.2f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
