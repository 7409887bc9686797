"""Build docs/faults.md from the fault rows of the last test run.

The fault tests add a row each (fault, what must happen, what happened) when they pass, their
teardown included; each test session writes its rows to a results file of its own outside the
repository (test/conftest.py: agv_nodes_fault_rows.PID.json in the temporary directory, or
`AGV_FAULT_RESULTS`) and names it in its summary line `fault table: N rows in FILE`. This
command turns that run's rows into the table, saying which run it was: run it after a full
`./agv.sh test` to refresh the committed docs/faults.md.

Run: .venv/bin/python test/fault_table.py --results FILE [--output docs/faults.md]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parent.parent
HEAD = """# Faults tried and what the truck did

Every row is asserted by the test it names; a row appears only when its test passed. Built by
`python test/fault_table.py` from {run}. Times are simulated.

| fault | expected | observed | test |
|---|---|---|---|
"""


def main() -> int:
    """Entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--results', type=Path, required=True,
                    help="the session's results file (its line `fault table: N rows in FILE`)")
    ap.add_argument('--output', type=Path, default=REPO / 'docs' / 'faults.md')
    args = ap.parse_args()
    results = json.loads(args.results.read_text())
    commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=REPO,
                            capture_output=True, text=True).stdout.strip() or 'unknown'
    run = (f'a run of {results["tests_collected"]} tests ({results["tests_failed"]} failed) '
           f'on commit {commit}')
    rows = ''.join(f'| {fault} | {" | ".join(row)} |\n'
                   for fault, row in sorted(results['rows'].items()))
    args.output.write_text(HEAD.format(run=run) + rows)
    print(f'{args.output}: {len(results["rows"])} rows from {run}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
