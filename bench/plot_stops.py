"""Plot the stop benchmark's per-run CSVs: stop error per configuration (fig 7.15 style).

Run: .venv/bin/python bench/plot_stops.py [CSV ...] [--out bench/results/stops.png]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
import sys

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('csv', nargs='*', type=Path,
                    default=sorted(Path('bench/results').glob('stops*.csv')))
    ap.add_argument('--out', type=Path, default=Path('bench/results/stops.png'))
    args = ap.parse_args()
    groups: dict[str, list[float]] = {}
    for path in args.csv:
        with path.open() as f:
            for row in csv.DictReader(f):
                speed = {'55': 0.7, '80': 1.0}.get(row['demand'], row['demand'])
                key = f'{row["mode"]}\n{speed} m/s, {float(row["payload"]):.0f} kg'
                groups.setdefault(key, [])
                if row['ok'] == 'True' and row['error_mm']:
                    groups[key].append(float(row['error_mm']))
    fig, ax = plt.subplots(figsize=(11, 4.5))
    for i, (key, errors) in enumerate(groups.items()):
        ax.plot([i] * len(errors), errors, 'o', alpha=0.4, color='tab:blue' if 'friction'
                in key else 'tab:orange')
        if not errors:
            ax.text(i, 5, 'no stop\nat the\nmarker', ha='center', fontsize=7, color='tab:red')
    ax.axhline(0, color='k', lw=0.8)
    ax.axhspan(-5, 5, color='tab:green', alpha=0.15, label='controlled goal +-5 mm')
    ax.set_xticks(range(len(groups)), list(groups), fontsize=7)
    ax.set_ylabel('stop error (mm, + = past the marker centre)')
    ax.set_title('Stop error over repeated stops (bench/stop_bench.py)')
    ax.legend(loc='upper left')
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f'wrote {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
