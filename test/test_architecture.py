"""The architecture's contracts (.importlinter), checked by import-linter's lint-imports.

The cores, the world's physics, the lock-step harness and the protocol code import neither
rclpy nor a message package, however indirectly. A second test plants such an import in a copy
of the package and watches the check break, so the contracts do name the modules they guard.
"""

from __future__ import annotations

from pathlib import Path
import shutil
import subprocess

import pytest

from conftest import PYTHON, REPO

pytestmark = pytest.mark.linter
LINT_IMPORTS = str(Path(PYTHON).parent / 'lint-imports')


def lint_imports(root: Path) -> subprocess.CompletedProcess:
    """Run lint-imports on the package under `root` (its .importlinter)."""
    return subprocess.run([LINT_IMPORTS, '--no-cache'], cwd=root, capture_output=True,
                          text=True, timeout=120)


@pytest.mark.timeout(150)
def test_the_cores_and_protocols_are_ros_free():
    res = lint_imports(REPO)
    assert res.returncode == 0 and 'Contracts: 2 kept, 0 broken.' in res.stdout, (
        res.stdout[-3000:] + res.stderr[-1000:])


@pytest.mark.timeout(150)
def test_an_import_of_rclpy_planted_in_a_core_breaks_the_contract(tmp_path):
    shutil.copytree(REPO / 'agv_nodes', tmp_path / 'agv_nodes',
                    ignore=shutil.ignore_patterns('__pycache__', '*.so'))
    shutil.copy(REPO / '.importlinter', tmp_path)
    core = tmp_path / 'agv_nodes' / 'traction' / 'core.py'
    core.write_text('import rclpy  # noqa\n' + core.read_text())
    (tmp_path / 'agv_nodes' / 'vda5050' / 'order.py').open('a').write('import std_msgs\n')
    res = lint_imports(tmp_path)
    assert res.returncode != 0, res.stdout[-2000:]
    assert 'Contracts: 0 kept, 2 broken.' in res.stdout, res.stdout[-3000:]
    assert 'agv_nodes.traction.core -> rclpy' in res.stdout, res.stdout[-3000:]
