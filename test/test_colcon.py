"""The ROS-native path: colcon builds the package into a workspace, as on a real Jazzy install.

After `source install/setup.bash`, every console script is where `ros2 run agv_nodes <name>`
looks (install/agv_nodes/lib/agv_nodes/<name>), and the installed package finds its schemas and
config through ament_index (share/agv_nodes), not through the source tree.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path
import subprocess

import pytest

from conftest import PYTHON, REPO

pytestmark = pytest.mark.slow
COLCON = str(Path(PYTHON).parent / 'colcon')


def console_scripts() -> list[str]:
    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    kw = {k.arg: k.value for k in call.keywords}
    entries = ast.literal_eval(kw['entry_points'])['console_scripts']
    return [e.split('=')[0].strip() for e in entries]


@pytest.fixture(scope='module')
def workspace(tmp_path_factory) -> Path:
    ws = tmp_path_factory.mktemp('colcon_ws')
    res = subprocess.run([COLCON, '--log-base', 'log', 'build', '--base-paths', str(REPO),
                          '--build-base', 'build', '--install-base', 'install'],
                         cwd=ws, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    return ws


def in_workspace(ws: Path, command: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ('AMENT_PREFIX_PATH', 'PYTHONPATH')}
    return subprocess.run(['bash', '-c', f'source install/setup.bash && {command}'], cwd=ws,
                          env=env, capture_output=True, text=True, timeout=120)


def test_ros2_run_executables_exist(workspace):
    lib = workspace / 'install' / 'agv_nodes' / 'lib' / 'agv_nodes'
    for name in console_scripts():
        exe = lib / name
        assert exe.is_file() and os.access(exe, os.X_OK), f'{name} missing from {lib}'


def test_installed_package_finds_share_via_ament_index(workspace):
    share = workspace / 'install' / 'agv_nodes' / 'share' / 'agv_nodes'
    assert (share / 'package.xml').is_file()
    installed = {p.name for p in (share / 'msg_schemas').glob('*.yaml')}
    assert installed == {p.name for p in (REPO / 'msg_schemas').glob('*.yaml')}
    probe = ('cd / && python -c "import agv_nodes.package_share as p, '
             'ament_index_python.packages as a; '
             "print(p.__file__); print(p.share_dir()); "
             "print(a.get_package_share_directory('agv_nodes'))\"")
    res = in_workspace(workspace, probe.replace('python', PYTHON, 1))
    assert res.returncode == 0, res.stderr
    module, share_dir, via_index = res.stdout.split()
    assert module.startswith(str(workspace / 'install'))  # the installed copy, not the source
    assert Path(share_dir) == Path(via_index) == share


def test_installed_tool_runs(workspace):
    res = in_workspace(workspace, 'install/agv_nodes/lib/agv_nodes/agv-records list')
    assert res.returncode == 0, res.stderr
    assert 'navigation_status' in res.stdout


def test_installed_package_has_its_parameter_declarations(workspace):
    probe = ('cd / && python -c "import agv_nodes.world.settings as w, agv_nodes.settings as s; '
             'print(w.__file__); print(len(s.parameters(w.WorldParams)))"')
    res = in_workspace(workspace, probe.replace('python', PYTHON, 1))
    assert res.returncode == 0, res.stderr
    module, count = res.stdout.split()
    assert module.startswith(str(workspace / 'install'))
    from agv_nodes.settings import parameters
    from agv_nodes.world.settings import WorldParams
    assert int(count) == len(parameters(WorldParams)) > 50


def test_installed_package_has_its_compiled_kernels(workspace):
    """The world's, the position sensor's and the codec's C, built into the install."""
    probe = ('cd / && python -c "from agv_nodes.world import kernels; '
             'from agv_nodes.position_sensor import kernels as sensor; '
             'from agv_nodes.records import compiled_paths as codec; '
             'print(kernels.compiled.__file__, sensor.compiled.__file__, '
             'codec.compiled.__file__)"')
    res = in_workspace(workspace, probe.replace('python', PYTHON, 1))
    assert res.returncode == 0, res.stderr
    built = res.stdout.split()
    assert len(built) == 3, res.stdout
    for path in built:
        assert path.startswith(str(workspace / 'install')), path
