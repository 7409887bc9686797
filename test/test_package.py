"""Packaging and style: package.xml and setup.py agree; ruff is clean at 99 columns."""

from __future__ import annotations

import ast
import re
import subprocess
import xml.etree.ElementTree as ET

import pytest

from conftest import PYTHON, REPO

pytestmark = pytest.mark.linter


def setup_py_keywords() -> dict:
    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    return {k.arg: k.value for k in call.keywords}


def test_package_xml_format3_and_dependencies():
    root = ET.parse(REPO / 'package.xml').getroot()
    assert root.tag == 'package' and root.get('format') == '3'
    exec_deps = {e.text for e in root.findall('exec_depend')}
    assert {'rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'nav_msgs',
            'visualization_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'std_srvs',
            'python3-numpy', 'python3-yaml'} <= exec_deps
    assert {e.text for e in root.findall('test_depend')} >= {'python3-pytest'}
    assert root.find('export/build_type').text == 'ament_python'


def test_every_package_xml_dependency_is_a_rosdep_key():
    """`rosdep install --from-paths src` resolves every key: each is one of ros/rosdistro's.

    test/data/rosdep_keys.txt lists rosdistro's keys and Jazzy's package names (its header says
    from which commit and how); what rosdep cannot install (amqtt) stays a pip dependency,
    named in a comment of package.xml.
    """
    root = ET.parse(REPO / 'package.xml').getroot()
    keys = {line.strip() for line in (REPO / 'test' / 'data' / 'rosdep_keys.txt').read_text()
            .splitlines() if line.strip() and not line.startswith('#')}
    deps = [e.text for tag in ('depend', 'build_depend', 'exec_depend', 'test_depend',
                               'buildtool_depend') for e in root.findall(tag)]
    assert deps and [d for d in deps if d not in keys] == []


def test_package_xml_and_setup_py_agree():
    root = ET.parse(REPO / 'package.xml').getroot()
    kw = setup_py_keywords()
    setup_src = (REPO / 'setup.py').read_text()
    name = re.search(r"package_name = '([^']+)'", setup_src).group(1)
    assert name == root.find('name').text == 'agv_nodes'
    assert ast.literal_eval(kw['version']) == root.find('version').text
    assert ast.literal_eval(kw['license']) == root.find('license').text
    from agv_nodes import __version__

    assert __version__ == root.find('version').text
    assert (REPO / 'resource' / name).is_file()


def test_setup_cfg_script_dir_for_ros2_run():
    text = (REPO / 'setup.cfg').read_text()
    assert 'script_dir=$base/lib/agv_nodes' in text
    assert 'install_scripts=$base/lib/agv_nodes' in text


def test_setup_py_installs_every_shared_file():
    """data_files cover every schema, config file and launch file of the tree."""
    out = subprocess.run(
        [PYTHON, '-c', 'import runpy, setuptools, json, sys\n'
         'seen = {}\n'
         'setuptools.setup = lambda **kw: seen.update(kw)\n'
         "runpy.run_path('setup.py')\n"
         "print(json.dumps(seen['data_files']))"],
        cwd=REPO, capture_output=True, text=True, check=True)
    import json

    installed = {f for _dest, files in json.loads(out.stdout) for f in files}
    tree = {str(p.relative_to(REPO)) for top in ('msg_schemas', 'config')
            for p in (REPO / top).rglob('*') if p.is_file()}
    tree |= {str(p.relative_to(REPO)) for p in (REPO / 'launch').glob('*.launch.py')}
    assert tree <= installed
    assert {'package.xml', 'resource/agv_nodes'} <= installed


def test_console_scripts_point_at_main_functions():
    kw = setup_py_keywords()
    scripts = ast.literal_eval(kw['entry_points'])['console_scripts']
    assert scripts
    import importlib

    for entry in scripts:
        name, target = (s.strip() for s in entry.split('='))
        module, func = target.split(':')
        assert callable(getattr(importlib.import_module(module), func)), name


def test_ruff_clean():
    res = subprocess.run([PYTHON, '-m', 'ruff', 'check', '.'], cwd=REPO, capture_output=True,
                         text=True)
    assert res.returncode == 0, res.stdout + res.stderr
