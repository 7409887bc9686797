"""bench/mutation_bench.py's list stays in step with the code (no mutation is run here)."""

from __future__ import annotations

from pathlib import Path
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / 'bench'))
import mutation_bench  # noqa: E402
from mutation_bench import MUTATIONS, Mutation, Result, apply, problems, table  # noqa: E402


@pytest.mark.timeout(30)
def test_every_original_text_occurs_exactly_once_and_every_named_test_exists():
    assert problems(REPO) == []


@pytest.mark.timeout(30)
@pytest.mark.parametrize('mutation', MUTATIONS, ids=[m.id for m in MUTATIONS])
def test_the_original_text_occurs_once_in_its_file(mutation):
    assert (REPO / mutation.file).read_text().count(mutation.original) == 1


@pytest.mark.timeout(10)
def test_the_list_covers_the_safety_areas():
    files = {m.file for m in MUTATIONS}
    areas = ('agv_nodes/records/e2e.py', 'agv_nodes/records/ports.py',
             'agv_nodes/traction/core.py', 'agv_nodes/executive/faults.py',
             'agv_nodes/world/core.py', 'agv_nodes/communications/task_language.py')
    assert set(areas) <= files
    assert any(f.startswith('agv_nodes/vda5050/') for f in files)
    assert len(MUTATIONS) >= 24


def _repo(tmp_path: Path, text: str) -> Path:
    (tmp_path / 'pkg').mkdir()
    (tmp_path / 'pkg' / 'code.py').write_text(text)
    (tmp_path / 'test').mkdir()
    (tmp_path / 'test' / 'test_code.py').write_text('def test_it():\n    pass\n')
    return tmp_path


def _mutation(original: str, test: str = 'test/test_code.py::test_it') -> Mutation:
    return Mutation('m', 'pkg/code.py', original, 'x = 2', 'what', (test,))


@pytest.mark.timeout(10)
def test_a_text_gone_twice_or_a_missing_test_is_named(tmp_path):
    repo = _repo(tmp_path, 'x = 1\ny = 1\ny = 1\n')
    assert problems(repo, (_mutation('x = 1'),)) == []
    assert problems(repo, (_mutation('z = 1'),)) == \
        ['m: the original text occurs 0 times in pkg/code.py, not once']
    assert problems(repo, (_mutation('y = 1'),)) == \
        ['m: the original text occurs 2 times in pkg/code.py, not once']
    assert problems(repo, (_mutation('x = 1', 'test/test_code.py::test_gone'),)) == \
        ['m: no test test/test_code.py::test_gone']
    assert problems(repo, (_mutation('x = 1'), _mutation('x = 1'))) == ['m: id given twice']


@pytest.mark.timeout(10)
def test_a_mutation_applies_by_exact_text_or_says_why_not(tmp_path):
    repo = _repo(tmp_path, 'x = 1\n')
    assert apply(repo, _mutation('x = 1')) == ''
    assert (repo / 'pkg' / 'code.py').read_text() == 'x = 2\n'
    assert apply(repo, _mutation('x = 1')) == 'the original text occurs 0 times in pkg/code.py'


@pytest.mark.timeout(10)
def test_the_table_has_a_row_each_and_ends_with_the_count():
    m = _mutation('x = 1')
    text = table([Result(m, 'caught', 'test/t.py::test_a', 1.0),
                  Result(m, 'survived', '', 2.0)], 'cmd --jobs 1')
    lines = text.strip().splitlines()
    assert lines[-1] == 'mutations caught: 1 of 2'
    assert sum(line.startswith('| m |') for line in lines) == 2
    assert 'cmd --jobs 1' in lines
    assert mutation_bench.DDS_LOCK == '/tmp/agv-dds.lock'
