"""The foundation: cores without rclpy, rclpy's private attributes, one source of settings."""

from pathlib import Path
import subprocess
import sys
import time

import pytest

from agv_nodes.settings import (
    ParameterFileError,
    SettingError,
    build,
    parameter_file_values,
    parameters,
    settings_from_file,
)

REPO = Path(__file__).resolve().parent.parent
CORES = ('agv_nodes.traction.core', 'agv_nodes.navigation.core', 'agv_nodes.position_sensor.core',
         'agv_nodes.route_following.core', 'agv_nodes.executive.core',
         'agv_nodes.communications.core', 'agv_nodes.load_handling.core', 'agv_nodes.world.core',
         'agv_nodes.harness', 'agv_nodes.settings')


@pytest.mark.timeout(60)
def test_every_core_and_the_harness_import_without_rclpy():
    """The cores are ROS-free: they import with every ROS package hidden."""
    hide = ('import sys\n'
            'class Hidden:\n'
            '    def find_spec(self, name, path=None, target=None):\n'
            "        top = name.split('.')[0]\n"
            "        if top in ('rclpy', 'rosgraph_msgs', 'std_msgs', 'sensor_msgs', "
            "'diagnostic_msgs', 'rcl_interfaces', 'geometry_msgs', 'nav_msgs'):\n"
            "            raise ImportError(f'{name} hidden')\n"
            'sys.meta_path.insert(0, Hidden())\n'
            + ''.join(f'import {m}\n' for m in CORES)
            + 'from agv_nodes.harness import truck\n'
            "truck('demo_1983').run(0.5)\n"
            "print('ok')\n")
    run = subprocess.run([sys.executable, '-c', hide], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0 and run.stdout.strip() == 'ok', run.stderr


@pytest.mark.wall_clock
def test_the_rclpy_internals_work_on_the_installed_rclpy():
    """Each private attribute used (agv_nodes/rclpy_internals.py) is there and does its job."""
    import rclpy
    from std_msgs.msg import String

    from agv_nodes import rclpy_internals as internals

    assert internals.check_version(), internals.rclpy_version()
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '-p', 'given:=7', '-p', 'use_sim_time:=true'],
               context=context)
    try:
        node = rclpy.create_node('internals_probe', context=context)
        assert internals.parameter_overrides(node)['given'] == 7
        time_source = internals.drop_clock_reader(node)
        assert time_source is not None and time_source._clock_sub is None
        assert node.count_subscribers('/clock') == 0
        pub = node.create_publisher(String, 'probe', 10)
        sub = node.create_subscription(String, 'probe', lambda _m: None, 10, raw=True)
        for k in range(3):
            pub.publish(String(data=f'm{k}'))
        taken = []
        for _ in range(50):  # intra-process delivery is quick but not instant
            taken += [raw for raw, _info in internals.take_all(sub, 10)]
            if len(taken) == 3:
                break
            time.sleep(0.02)
        assert len(taken) == 3 and all(isinstance(raw, bytes) for raw in taken)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_settings_are_checked_once_with_a_named_parameter():
    from agv_nodes.traction.settings import TractionParams

    assert build(TractionParams, {'kp': 2}).kp == 2.0  # an integer for a float setting
    for values, reason in (({'kpx': 1.0}, 'no such parameter'),
                           ({'kp': -1.0}, 'outside'),
                           ({'control': 'fast'}, 'not one of'),
                           ({'field_duty': 1.5}, 'must be an integer')):
        with pytest.raises(SettingError, match=reason):
            build(TractionParams, values)


def test_a_parameter_file_typo_names_the_file_node_and_key(tmp_path):
    from agv_nodes.traction.settings import TractionParams

    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**/traction:\n  ros__parameters:\n    comand_timeout: 0.1\n')
    with pytest.raises(ParameterFileError, match=r"bad.yaml: node traction: unknown parameter "
                       r"'comand_timeout'"):
        settings_from_file(TractionParams, bad, 'traction')
    broken = tmp_path / 'broken.yaml'
    broken.write_text('/**/traction:\n  ros__parameters:\n    kp: [1, 2\n')
    with pytest.raises(ParameterFileError, match=r'broken.yaml: line \d+: not YAML'):
        settings_from_file(TractionParams, broken, 'traction')


def test_shared_sections_apply_to_every_node_and_named_ones_to_theirs(tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text('/**:\n  ros__parameters: {a: 1}\n/**/traction:\n  ros__parameters: {b: 2}\n'
                 '/agv2/navigation:\n  ros__parameters:\n    wire: {kp: 3}\n')
    assert parameter_file_values(f, 'traction') == ({'a': 1}, {'b': 2})
    assert parameter_file_values(f, 'navigation', '/agv2') == ({'a': 1}, {'wire.kp': 3})
    assert parameter_file_values(f, 'navigation') == ({'a': 1}, {})


def test_every_setting_has_a_description_and_numbers_a_range():
    from agv_nodes.harness import truck

    h = truck('demo_1983')
    classes = {type(h.world.p)} | {type(core.p) for core in h.cores.values()}
    for cls in classes:
        for p in parameters(cls):
            assert p.spec.description, (cls.__name__, p.name)
            if p.kind in (int, float) and not p.spec.choices:
                assert p.spec.lo is not None and p.spec.hi is not None, (cls.__name__, p.name)


def test_the_parameter_reference_is_the_one_the_declarations_make():
    sys.path.insert(0, str(REPO / 'docs'))
    try:
        import parameter_table
    finally:
        sys.path.pop(0)
    assert (REPO / 'docs' / 'parameters.md').read_text() == parameter_table.page(), \
        'docs/parameters.md is stale: run docs/parameter_table.py'


def test_a_bad_declaration_names_its_file_class_and_key(tmp_path):
    from agv_nodes.settings import DefinitionError, _declaration
    for entry, words in [({'default': 1.0}, 'needs a mapping with default and description'),
                         ({'default': [], 'description': 'x'}, 'a list default needs a type'),
                         ({'default': 1, 'description': 'x', 'rnage': [0, 2]}, "'rnage'"),
                         ({'default': None, 'description': 'x'}, 'is not a bool')]:
        with pytest.raises(DefinitionError, match=words):
            _declaration('f.yaml: Cls.name', entry)
