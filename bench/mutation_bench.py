"""Mutations of the safety-critical code, each run against the tests that should catch it.

Each mutation replaces one exact text of one file by another, in a scratch copy of the
repository (`--tree worktree`, the default: the tracked and new files as they are in the working
tree, taken once at the start of a run; `--tree head`: HEAD's tracked tree, plus the
working-tree versions of the mutated file and of the test files named), and runs `pytest -x`
on its short list of test node ids there, with PYTHONPATH on the copy so that `agv_nodes`
imports from it. Verdict: caught (a test failed), survived (all passed: a test is missing) or
error (the text is gone, not exactly once in the file, or pytest could not run the tests: the
bench then fails loudly, so the list stays in step with the code). Before the mutations, the
unmutated copy must pass every test named (baseline), so a caught verdict means the mutation,
not a test that fails anyway.

The compiled kernels (agv_nodes/kernel_choice.py): `kernels='c'` copies the installed C
extensions into the copy (they run as installed); `kernels='python'` copies none, so the
Python code a C kernel stands in for is what runs (used where the mutated code is such code);
`kernels='build'` rebuilds the C extensions from the copy's (mutated) C source. DDS tests run
one at a time under `flock /tmp/agv-dds.lock`.

Run: .venv/bin/python bench/mutation_bench.py [--list] [--only ID ...] [--jobs 1]
     [--tree worktree|head] [--no-baseline] [--output bench/results/mutation_bench.md]
test/test_mutation_bench.py checks, without running any, that every original text is still
in its file exactly once and every test named still exists.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import io
import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time

REPO = Path(__file__).resolve().parent.parent
PYTHON = REPO / '.venv' / 'bin' / 'python'
KERNELS = ('agv_nodes/world/_kernels', 'agv_nodes/position_sensor/_thresh',
           'agv_nodes/records/_codec')
DDS_LOCK = '/tmp/agv-dds.lock'
TEST_LIMIT_S = 900  # one pytest run of a mutation's tests

sys.path.insert(0, str(Path(__file__).resolve().parent))
from safety_mutations import MUTATIONS, Mutation  # noqa: E402  (bench/ is no package)


# -- checking the list ----------------------------------------------------------------------
def problems(repo: Path = REPO, mutations: tuple[Mutation, ...] = MUTATIONS) -> list[str]:
    """Say what is wrong with the list against the files in `repo` (empty: nothing)."""
    out = []
    ids = [m.id for m in mutations]
    out += [f'{i}: id given twice' for i in sorted({i for i in ids if ids.count(i) > 1})]
    for m in mutations:
        path = repo / m.file
        if not path.is_file():
            out.append(f'{m.id}: {m.file} does not exist')
            continue
        count = path.read_text().count(m.original)
        if count != 1:
            out.append(f'{m.id}: the original text occurs {count} times in {m.file}, not once')
        if m.original == m.replacement:
            out.append(f'{m.id}: the replacement is the original')
        if m.kernels not in ('c', 'python', 'build') or not m.tests:
            out.append(f'{m.id}: kernels {m.kernels!r} or no tests')
        for node in m.tests:
            test_file, _, name = node.partition('::')
            name = re.sub(r'\[.*', '', name.split('::')[-1])
            source = repo / test_file
            if not source.is_file() or not re.search(rf'def {name}\b', source.read_text()):
                out.append(f'{m.id}: no test {node}')
    return out


# -- the scratch copy -------------------------------------------------------------------------
def snapshot(repo: Path, tree: str) -> bytes:
    """Return the tree the copies start from, as a tar archive.

    'worktree': every tracked file and every new one git does not ignore, as they are in the
    working tree now (the code the list is checked against); 'head': the tracked tree at HEAD,
    over which each copy lays the working-tree mutated file and test files.
    """
    if tree == 'head':
        return subprocess.run(['git', 'archive', '--format=tar', 'HEAD'], cwd=repo, check=True,
                              capture_output=True).stdout
    names = subprocess.run(['git', 'ls-files', '-z', '--cached', '--others',
                            '--exclude-standard'], cwd=repo, check=True,
                           capture_output=True).stdout.decode().split('\0')
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode='w') as archive:
        # not the built kernels: each copy takes those its mutation asks for (scratch)
        for name in sorted(n for n in names
                           if n and not n.endswith('.so') and (repo / n).is_file()):
            archive.add(repo / name, arcname=name, recursive=False)
    return out.getvalue()


def scratch(repo: Path, tree: bytes, overlay: set[str], kernels: str) -> Path:
    """Make a scratch copy of `tree`, the working-tree `overlay` files, the kernels asked."""
    copy = Path(tempfile.mkdtemp(prefix='agv-mutant-'))
    with tarfile.open(fileobj=io.BytesIO(tree)) as archive:
        archive.extractall(copy, filter='data')
    for name in overlay:
        (copy / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(repo / name, copy / name)
    if kernels == 'c':
        for stem in KERNELS:
            for built in (repo / stem).parent.glob(Path(stem).name + '.*.so'):
                shutil.copy2(built, copy / stem.rsplit('/', 1)[0] / built.name)
    return copy


def build_kernels(copy: Path) -> None:
    """Build the C extensions in place in `copy` (from its own C source)."""
    run = subprocess.run([str(PYTHON), 'setup.py', '-q', 'build_ext', '--inplace'], cwd=copy,
                         capture_output=True, text=True)
    missing = [s for s in KERNELS if not list((copy / s).parent.glob(Path(s).name + '.*.so'))]
    if run.returncode or missing:
        raise RuntimeError(f'C build failed in {copy}: {missing}\n{run.stderr[-2000:]}')


def pytest(copy: Path, tests: tuple[str, ...], dds: bool) -> tuple[int, str, str]:
    """Run `pytest -x` on `tests` in `copy`: (exit code, first failed node id, output tail)."""
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(copy)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]),
        'PYTHONDONTWRITEBYTECODE': '1'}
    command = [str(PYTHON), '-m', 'pytest', '-x', '-q', '-rfE', '-p', 'no:cacheprovider',
               *tests]
    command = ['flock', DDS_LOCK, *command] if dds else ['nice', '-n', '10', *command]
    try:
        run = subprocess.run(command, cwd=copy, env=env, capture_output=True, text=True,
                             timeout=TEST_LIMIT_S)
    except subprocess.TimeoutExpired:
        return 124, '', f'no result within {TEST_LIMIT_S} s'
    failed = re.search(r'^(?:FAILED|ERROR) (.+?)(?: - .*)?$', run.stdout, re.MULTILINE)
    return run.returncode, failed.group(1) if failed else '', run.stdout[-3000:]


# -- running ------------------------------------------------------------------------------------
@dataclass
class Result:
    """What one mutation did: verdict caught / survived / error."""

    mutation: Mutation
    verdict: str
    caught_by: str
    seconds: float
    detail: str = ''


def apply(copy: Path, m: Mutation) -> str:
    """Apply `m` in `copy`; '' or why it did not apply."""
    path = copy / m.file
    text = path.read_text()
    if text.count(m.original) != 1:
        return f'the original text occurs {text.count(m.original)} times in {m.file}'
    path.write_text(text.replace(m.original, m.replacement))
    return ''


def overlay_of(tests: tuple[str, ...], *files: str, head: bool) -> set[str]:
    """Return the files laid over HEAD's tree: the mutated file and the test files."""
    return {*files, *(node.split('::')[0] for node in tests)} if head else set()


def run_mutation(repo: Path, tree: bytes, m: Mutation, head: bool = False) -> Result:
    """Apply `m` in a scratch copy of its own and run its tests there."""
    start = time.monotonic()
    copy = scratch(repo, tree, overlay_of(m.tests, m.file, head=head), m.kernels)
    try:
        if why := apply(copy, m):
            return Result(m, 'error', '', time.monotonic() - start, why)
        if m.kernels == 'build':
            build_kernels(copy)
        code, failed, tail = pytest(copy, m.tests, m.dds)
    finally:
        shutil.rmtree(copy, ignore_errors=True)
    seconds = time.monotonic() - start
    if code == 0:
        return Result(m, 'survived', '', seconds)
    if code == 1 and failed:
        return Result(m, 'caught', failed, seconds)
    return Result(m, 'error', failed, seconds, f'pytest exit {code}:\n{tail}')


def baseline(repo: Path, tree: bytes, mutations: list[Mutation],
             head: bool = False) -> list[str]:
    """Run every named test on the unmutated copy; return what failed (empty: all passed)."""
    failures = []
    groups: dict[tuple[str, bool], list[str]] = {}
    for m in mutations:
        kernels = 'c' if m.kernels == 'build' else m.kernels  # the installed build is HEAD's
        tests = groups.setdefault((kernels, m.dds), [])
        tests += [t for t in m.tests if t not in tests]
    for (kernels, dds), tests in sorted(groups.items()):
        files = {m.file for m in mutations}
        copy = scratch(repo, tree, overlay_of(tuple(tests), *files, head=head), kernels)
        try:
            for batch in ([[t] for t in tests] if dds else [tests]):
                code, failed, tail = pytest(copy, tuple(batch), dds)
                if code != 0:
                    failures.append(f'kernels={kernels}: exit {code} {failed}\n{tail}')
        finally:
            shutil.rmtree(copy, ignore_errors=True)
    return failures


def shown(node: str, most: int = 40) -> str:
    """Return a test node id for the table: long parameters cut, '|' escaped."""
    name, bracket, params = node.partition('[')
    if bracket and len(params) > most:
        params = params[:most - 4] + '...]'
    return (name + bracket + params).replace('|', '\\|')


def table(results: list[Result], command: str) -> str:
    """Return the Markdown table of `results`, headed by the command that made it."""
    caught = sum(r.verdict == 'caught' for r in results)
    lines = ['# Mutation benchmark of the safety-critical code', '', 'Produced by:', '',
             '```bash', command, '```', '',
             'Each row: one mutation of the safety-critical code (bench/mutation_bench.py has '
             'the exact original text and its replacement), applied in a scratch copy of the '
             'repository, and `pytest -x` on the tests named for it there. `caught by` is the '
             'test that failed first; `survived` means every named test passed with the '
             'mutation in place (a missing test). The unmutated copy passed every named test '
             'first. Kernels: `c` the installed C extensions, `python` none (the Python code '
             'they stand in for runs), `build` the C rebuilt from the mutated source. Seconds: '
             'wall time of the copy and the tests (for DDS tests with the wait for '
             f'`{DDS_LOCK}`), on a 2-core machine shared with other work.',
             '', '| id | what it breaks | where | kernels | caught by | verdict | s |',
             '|---|---|---|---|---|---|---|']
    for r in results:
        m = r.mutation
        lines.append(f'| {m.id} | {m.what} | `{m.file}` | {m.kernels} | '
                     f'{f"`{shown(r.caught_by)}`" if r.caught_by else "-"} | {r.verdict} | '
                     f'{r.seconds:.1f} |')
    lines += ['', f'mutations caught: {caught} of {len(results)}', '']
    return '\n'.join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--only', nargs='+', metavar='ID', help='run only these mutations')
    ap.add_argument('--list', action='store_true', help='list the mutations and stop')
    ap.add_argument('--jobs', type=int, default=1, help='mutations at once (default 1)')
    ap.add_argument('--output', type=Path, help='write the Markdown table here')
    ap.add_argument('--tree', choices=('worktree', 'head'), default='worktree',
                    help='copy the working tree (default) or HEAD plus the mutated file')
    ap.add_argument('--no-baseline', action='store_true',
                    help='skip running the named tests on the unmutated copy first')
    args = ap.parse_args()
    if wrong := problems(REPO):
        print('mutation list out of step with the code:\n  ' + '\n  '.join(wrong))
        return 2
    chosen = list(MUTATIONS)
    if args.only:
        unknown = sorted(set(args.only) - {m.id for m in MUTATIONS})
        if unknown:
            print(f'unknown mutation ids: {", ".join(unknown)} (--list shows them)')
            return 2
        chosen = [m for m in MUTATIONS if m.id in args.only]
    if args.list:
        for m in chosen:
            print(f'{m.id:28} {m.file}: {m.what}\n{"":28} tests: {" ".join(m.tests)}')
        return 0
    tree, head = snapshot(REPO, args.tree), args.tree == 'head'
    if not args.no_baseline:
        if failures := baseline(REPO, tree, chosen, head):
            print('the named tests fail without any mutation:\n' + '\n'.join(failures))
            return 2
        print('baseline: every named test passes unmutated', flush=True)
    results: list[Result] = []

    def one(m: Mutation) -> Result:
        r = run_mutation(REPO, tree, m, head)
        print(f'{m.id:28} {r.verdict:9} {r.seconds:6.1f} s {r.caught_by}', flush=True)
        if r.verdict == 'error':
            print(r.detail, flush=True)
        return r

    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(one, chosen))
    command = ' '.join(['.venv/bin/python', 'bench/mutation_bench.py', *sys.argv[1:]])
    text = table(results, command)
    print(text)
    if args.output:
        args.output.write_text(text)
    return 1 if any(r.verdict == 'error' for r in results) else 0


if __name__ == '__main__':
    sys.exit(main())
