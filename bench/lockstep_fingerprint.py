"""The seeded lock-step run of the whole demonstration programme, as a comparable fingerprint.

Prints (or writes with --output) a JSON document of everything a refactoring or a speed-up must
leave unchanged: every world event (kind, marker, sim time, stop error, speed, lateral offset),
every task's final state and cause, and the stop errors. Two runs of the same code give the
same document; `--compare OLD.json` reports the first difference against an earlier one.

Run: .venv/bin/python bench/lockstep_fingerprint.py [--output F] [--compare OLD.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys
import time
from typing import Any

from agv_nodes.harness import DEMO_PROGRAMME, submit, truck


def fingerprint(seed: int = 1) -> dict[str, Any]:
    """Run the programme in lock step and collect what must not change."""
    return timed_fingerprint(seed)[0]


def timed_fingerprint(seed: int = 1) -> tuple[dict[str, Any], float, float]:
    """Return the fingerprint, and the wall and CPU seconds the programme's steps took.

    Only the steps are timed: building the truck and parsing the tasks are not the harness's
    speed. bench/graph_bench.py --baseline runs this against another commit's agv_nodes.
    """
    h = truck('demo_1983', seed=seed)
    for text in DEMO_PROGRAMME:
        submit(h, text)
    comms, executive = h.cores['communications'], h.cores['executive']
    wall, cpu = time.perf_counter(), time.process_time()
    while comms.queue or executive.mode == 'running':
        h.step()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    events = [{k: e[k] for k in ('event', 'marker', 'time', 'error', 'speed', 'lateral')}
              for e in h.events]
    return {
        'seed': seed,
        'simulated_s': round(h.now, 6),
        'tasks': [list(r) for r in comms.results],
        'stops_mm': [e['error'] for e in h.events if e['event'] == 'stopped' and e['marker']],
        'events': events,
    }, wall, cpu


def first_difference(old: Any, new: Any, where: str = '') -> str | None:
    """Where two fingerprints first differ (None when they are equal)."""
    if type(old) is not type(new):
        return f'{where}: {old!r} != {new!r}'
    if isinstance(old, dict):
        for key in sorted(set(old) | set(new)):
            if key not in old or key not in new:
                return f'{where}.{key}: only in {"new" if key in new else "old"}'
            found = first_difference(old[key], new[key], f'{where}.{key}')
            if found:
                return found
        return None
    if isinstance(old, list):
        for i, (a, b) in enumerate(zip(old, new, strict=False)):
            found = first_difference(a, b, f'{where}[{i}]')
            if found:
                return found
        return None if len(old) == len(new) else f'{where}: {len(old)} != {len(new)} items'
    return None if old == new else f'{where}: {old!r} != {new!r}'


def main() -> int:
    """Entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--output', type=Path, help='write the fingerprint here')
    ap.add_argument('--compare', type=Path, help='an earlier fingerprint to compare with')
    args = ap.parse_args()
    fp = fingerprint(args.seed)
    text = json.dumps(fp, indent=1)
    if args.output:
        args.output.write_text(text + '\n')
    else:
        print(text)
    print(f'{len(fp["events"])} events, {len(fp["tasks"])} tasks, stops (mm): '
          f'{fp["stops_mm"]}', file=sys.stderr)
    if args.compare:
        difference = first_difference(json.loads(args.compare.read_text()), fp)
        print('identical' if difference is None else f'differs at {difference}',
              file=sys.stderr)
        return 0 if difference is None else 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
