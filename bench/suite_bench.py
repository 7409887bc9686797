"""Test-suite benchmark: the wall time of `./agv.sh test`, and where it goes.

Runs the whole suite through `./agv.sh test` once per `--workers` value (AGV_TEST_WORKERS: 0, the
default, is one process; 2 is the two lanes of test/conftest.py) with this file as a plugin that
notes each test's wall time and CPU (its process and the child processes it waited for: a
graph's nodes). Prints a Markdown table (bench/results/test_suite.md): per run the wall time,
the CPU, the cores kept busy on average, and per lane (the tests over DDS, the rest) the tests'
wall time and CPU; then the modules that take longest.

Run: .venv/bin/python bench/suite_bench.py [--workers 2 --workers 0] [-- PYTEST ARGS]
"""

from __future__ import annotations

import argparse
from collections import defaultdict
import json
import os
from pathlib import Path
import resource
import subprocess
import sys
import tempfile
import time

import pytest

REPO = Path(__file__).resolve().parent.parent
ROWS_ENV = 'AGV_SUITE_BENCH_ROWS'


# -- the plugin (loaded into pytest and its workers with -p suite_bench) -----------------------
def _cpu() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    waited = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + waited.ru_utime + waited.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):  # noqa: ANN001, ANN201 - pytest's hook
    """Note the test's wall time and CPU (set-up, call and tear-down)."""
    wall, cpu = time.monotonic(), _cpu()
    yield
    row = {'test': item.nodeid, 'wall': time.monotonic() - wall, 'cpu': _cpu() - cpu,
           'dds': item.get_closest_marker('dds') is not None,
           'worker': os.environ.get('PYTEST_XDIST_WORKER', 'main')}
    if path := os.environ.get(ROWS_ENV):
        with open(path, 'a') as rows:  # one short line per append: workers do not interleave
            rows.write(json.dumps(row) + '\n')


# -- the benchmark -----------------------------------------------------------------------------
def run_suite(workers: int, pytest_args: list[str]) -> dict:
    """Run `./agv.sh test` with `workers`; return its wall time, CPU, outcome and rows."""
    with tempfile.TemporaryDirectory() as tmp:
        rows_file = Path(tmp) / 'rows.jsonl'
        env = dict(os.environ, AGV_TEST_WORKERS=str(workers), **{ROWS_ENV: str(rows_file)},
                   PYTHONPATH=os.pathsep.join(filter(None, [str(REPO / 'bench'),
                                                            os.environ.get('PYTHONPATH')])))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.monotonic()
        done = subprocess.run([str(REPO / 'agv.sh'), 'test', '-q', '-p', 'suite_bench',
                               *pytest_args], cwd=REPO, env=env, capture_output=True,
                              text=True)
        wall = time.monotonic() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        rows = [json.loads(line) for line in rows_file.read_text().splitlines()] \
            if rows_file.exists() else []
    summary = next((line for line in reversed(done.stdout.splitlines())
                    if ' in ' in line and ('passed' in line or 'failed' in line)), '?')
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {'workers': workers, 'wall': wall, 'cpu': cpu, 'code': done.returncode,
            'summary': summary.strip('= '), 'rows': rows}


def lane_table(runs: list[dict]) -> list[str]:
    """Markdown: per run, the whole and the two lanes."""
    out = ['| measure | ' + ' | '.join(f'{r["workers"]} workers' if r['workers'] else
                                       'one process' for r in runs) + ' |',
           '|---|' + '---|' * len(runs)]

    def row(name: str, cell) -> None:
        out.append(f'| {name} | ' + ' | '.join(cell(r) for r in runs) + ' |')

    row('outcome', lambda r: r['summary'])
    row('wall time (s)', lambda r: f'{r["wall"]:.0f}')
    row('CPU, all processes (s)', lambda r: f'{r["cpu"]:.0f}')
    row('cores kept busy (of 2)', lambda r: f'{r["cpu"] / r["wall"]:.2f}')
    for lane, is_dds in (('tests over DDS', True), ('the other tests', False)):
        picked = [[x for x in r['rows'] if x['dds'] == is_dds] for r in runs]
        out.append(f'| {lane}: count | ' + ' | '.join(str(len(p)) for p in picked) + ' |')
        for key, name in (('wall', 'their wall time (s)'), ('cpu', 'their CPU (s)')):
            out.append(f'| {lane}: {name} | '
                       + ' | '.join(f'{sum(x[key] for x in p):.0f}' for p in picked) + ' |')
    return out


def module_table(run: dict, top: int) -> list[str]:
    """Markdown: the modules that take longest in `run`."""
    modules: dict[str, list] = defaultdict(lambda: [0, 0.0, 0.0, False])
    for x in run['rows']:
        m = modules[x['test'].split('::')[0].split('@')[0]]
        m[0] += 1
        m[1] += x['wall']
        m[2] += x['cpu']
        m[3] = m[3] or x['dds']
    out = ['| module | tests | DDS | wall (s) | CPU (s) | cores |', '|---|---|---|---|---|---|']
    for name, (n, wall, cpu, dds) in sorted(modules.items(), key=lambda kv: -kv[1][1])[:top]:
        out.append(f'| `{name}` | {n} | {"yes" if dds else ""} | {wall:.1f} | {cpu:.1f} | '
                   f'{cpu / wall if wall else 0:.2f} |')
    return out


def main() -> int:
    """Run the suite per --workers and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--workers', type=int, action='append',
                    help='AGV_TEST_WORKERS for one run (repeat for several; default 0)')
    ap.add_argument('--top', type=int, default=15, help='modules listed')
    ap.add_argument('pytest_args', nargs='*', help='after --: passed to pytest')
    args = ap.parse_args()
    runs = []
    for workers in args.workers or [0]:
        runs.append(run := run_suite(workers, args.pytest_args))
        print(f'{workers} workers: {run["summary"]} (exit {run["code"]}), '
              f'{run["wall"]:.0f} s wall', file=sys.stderr, flush=True)
    print('\n'.join(lane_table(runs)))
    print()
    print('\n'.join(module_table(runs[-1], args.top)))
    return max(r['code'] for r in runs)


if __name__ == '__main__':
    sys.exit(main())
