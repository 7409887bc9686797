"""Fuzzed records through the live graph: 100,000 by default, every one counted exactly.

The test's machinery at scale (test/fuzz_session.py, test/record_fuzz.py): the whole graph on a
ROS domain of its own, this process's probe node standing in as the named writer of every
record a sub-system node reads (the world's three inputs get it as a foreign writer), a
hand-shake on every topic, one reference record per protected topic, then hypothesis draws one
malformed record per topic per example, and every one is sent. Each reader's `/diagnostics` row
must show exactly what the independent oracle (test/record_oracle.py) says it must count, by
topic and reason, and exactly the reference and the records the oracle accepts as accepted.
Writes bench/results/fuzz_bench.md: records per topic and reason, counted, time.

Run: .venv/bin/python bench/fuzz_bench.py [--examples 5000] [--out bench/results/fuzz_bench.md]
"""

from __future__ import annotations

import argparse
from collections import Counter
import os
from pathlib import Path
import sys
import tempfile
import time
from typing import Any

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / 'test'))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--examples', type=int, default=5000,
                    help='records per topic (20 topics: 5000 gives 100,000)')
    ap.add_argument('--out', type=Path, default=REPO / 'bench' / 'results' / 'fuzz_bench.md')
    args = ap.parse_args()

    from agv_nodes.discovery import use_localhost_discovery
    from agv_nodes.graph.supervisor import claim_domain

    domain, _lock = claim_domain()  # never domain 0; held while the bench runs
    os.environ['ROS_DOMAIN_ID'] = str(domain)
    use_localhost_discovery()

    from fuzz_session import fuzzed_schemas, start_session
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st
    from record_fuzz import recipes

    schemas = fuzzed_schemas()
    session, stop = start_session(Path(tempfile.mkdtemp(prefix='fuzz_bench_')) / 'logs')
    try:
        t0 = time.monotonic()
        session.handshake()
        session.send_reference()
        t_send = time.monotonic()

        @settings(max_examples=args.examples, deadline=None, derandomize=True, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(batch=st.fixed_dictionaries({s.name: recipes(s) for s in schemas}))
        def fuzz(batch: dict) -> None:
            for name, recipe in batch.items():
                session.send(name, recipe)
            session.spin(0.04)  # the test's pace: no reader's queue overflows

        fuzz()
        sent_s = time.monotonic() - t_send
        left = session.wait_counted(wall_limit=300)
        counted_s = time.monotonic() - t_send
        manual = sum(bool(s['manual']) for s in session.statuses)
        still = session.max_speed < 0.005 and not session.events and not manual
        lines = table(session, schemas, args, domain, sent_s, counted_s,
                      time.monotonic() - t0, left, still)
    finally:
        stop()
    args.out.write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines))
    return 0 if not left and still else 1


def table(session: Any, schemas: list, args: argparse.Namespace, domain: int,
          sent_s: float, counted_s: float, total_s: float, left: dict,
          still: bool) -> list[str]:
    """Return the results page: the command, the totals, then one row per topic."""
    fuzzed = sum(session.by_recipe.values())
    sent = sum(session.fuzzed.values())
    reasons = sorted({reason for (_r, _n, reason) in session.due})
    verdict = 'every link counted exactly' if not left else f'NOT EXACT on {sorted(left)}'
    lines = [
        '# Fuzzed records through the live graph',
        '',
        'Produced by:',
        '',
        '```bash',
        f'.venv/bin/python bench/fuzz_bench.py --examples {args.examples}',
        '```',
        '',
        f'{sent:,} fuzzed records sent on {len(schemas)} record topics (plus the hand-shake and '
        f'reference records) in {sent_s:.0f} s, all counted {counted_s:.0f} s after the first '
        f'({total_s:.0f} s with the hand-shake; ROS domain {domain}, 2-core machine shared with '
        f'other work); {fuzzed:,} drawn, all sent. {sum(session.taken.values())} of them the '
        'oracle (test/record_oracle.py) accepts (a skipped counter completing a '
        'resynchronisation run) and the readers must take. '
        f'Result: {verdict}; truck '
        f'{"at rest, no world event, no fuzzed command acted on" if still else "MOVED or acted"}.',
        '',
        '`sent` is the fuzzed records on the topic; the reason columns are what each reader '
        'must count (every sub-system reader of a topic sees the same records in the same '
        'order), the verdicts of the oracle written apart from the codec and the reader; '
        '`accepted` is the fuzzed records it takes; the last column '
        "is how many readers' `/diagnostics` inputs rows showed exactly that since the "
        'hand-shake, and exactly the reference and those as accepted. `foreign_writer` is the '
        'world, '
        'which reads the probe as a foreign writer; at the other readers the probe is the named '
        "writer, so the graph's own writer of the record is the foreign one there (not counted "
        'here).',
        '',
        '| record | readers | sent | accepted | ' + ' | '.join(reasons)
        + ' | readers counting exactly |',
        '|---|---|---|---|' + '---|' * len(reasons) + '---|',
    ]
    links = set(session.links())
    wrong = set(left)
    for s in schemas:
        readers = [r for r in s.readers if (r, s.name) in links]
        per_reason: Counter[str] = Counter()
        for reader in (next((r for r in readers if not session.foreign(r)), None), 'world'):
            for (r, name, reason), n in session.due.items():
                if name == s.name and r == reader:
                    per_reason[reason] += n
        exact = sum((r, s.name) not in wrong for r in readers)
        cells = [str(per_reason.get(reason, '')) for reason in reasons]
        lines.append(f'| `{s.name}` | {", ".join(readers)} | {session.fuzzed[s.name]} | '
                     f'{session.taken[s.name] or ""} | ' + ' | '.join(cells)
                     + f' | {exact} of {len(readers)} |')
    return lines


if __name__ == '__main__':
    sys.exit(main())
