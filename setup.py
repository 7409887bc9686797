"""ament_python build description for agv_nodes (colcon, pip and pip -e all use this file)."""

from glob import glob
import os

from setuptools import Extension, find_packages, setup

package_name = 'agv_nodes'


def tree(top: str) -> list[tuple[str, list[str]]]:
    """Data-file entries installing every file below `top` into share/agv_nodes/`top`."""
    entries = []
    for folder, _dirs, files in sorted(os.walk(top)):
        files = sorted(os.path.join(folder, f) for f in files if not f.endswith('.pyc'))
        if files:
            entries.append((os.path.join('share', package_name, folder), files))
    return entries


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'examples']),
    # Every node's parameter declarations (agv_nodes/settings.py reads them at import).
    package_data={package_name: ['parameters.yaml', '*/parameters.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        *tree('msg_schemas'),
        *tree('config'),
    ],
    # Hot loops in C (agv_nodes/kernel_choice.py): the world's physics and optics, the position
    # sensor's THRESH, the record codec. Optional: without a C compiler the package installs
    # without them and runs the same arithmetic in Python. No fused multiply-adds, so the C
    # code gives the Python code's bits.
    ext_modules=[Extension(f'agv_nodes.{name}', [f'agv_nodes/{name.replace(".", "/")}.c'],
                           extra_compile_args=['-O2', '-ffp-contract=off'], optional=True)
                 for name in ('world._kernels', 'position_sensor._thresh', 'records._codec')],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='agv_nodes developers',
    maintainer_email='agv-nodes@example.org',
    description='ROS 2 reproduction of the 1983 Cableform AGV (Baker 1983, Rajagopalan 1991).',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            # nodes (ros2 run agv_nodes <node>)
            'communications = agv_nodes.communications.node:main',
            'dispatcher = agv_nodes.fleet.dispatcher_node:main',
            'executive = agv_nodes.executive.node:main',
            'live_view = agv_nodes.view.live:main',
            'load_handling = agv_nodes.load_handling.node:main',
            'navigation = agv_nodes.navigation.node:main',
            'position_sensor = agv_nodes.position_sensor.node:main',
            'recorder = agv_nodes.recorder:main',
            'route_following = agv_nodes.route_following.node:main',
            'traction = agv_nodes.traction.node:main',
            'vda5050_bridge = agv_nodes.vda5050.bridge_node:main',
            'world = agv_nodes.world.node:main',
            # tools
            'agv-demo = agv_nodes.demo:main',
            'agv-diag = agv_nodes.executive.diag_view:main',
            'agv-fleet-sim = agv_nodes.fleet.fleet_sim:main',
            'agv-launch = agv_nodes.graph.cli:main',
            'agv-layout = agv_nodes.world.layout_cli:main',
            'agv-records = agv_nodes.records.cli:main',
            'agv-report = agv_nodes.report:main',
        ],
    },
)
