"""World benchmark: core steps per second per layout, and the world node's CPU at real time.

The core is timed with its compiled kernels and with the Python code they stand in for (the
world parameter `kernels`, agv_nodes/world/kernels.py), alternated, the best of `--rounds`.

Run: .venv/bin/python bench/world_bench.py [--node-seconds 10] [--rounds 2]
Prints a Markdown table (bench/results/world_bench.md).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import subprocess
import sys
import time

from agv_nodes.discovery import use_localhost_discovery
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import WorldParams

REPO = Path(__file__).resolve().parent.parent
DRIVE = dict(armature_duty=60, field_duty=98, armature_enable=1, field_enable=1,
             field_forward=1, contactor=1, watchdog=0)
STEER = dict(mode='angle', enable=1, angle=0, left_speed=0, right_speed=0)
WHEELS = dict(mode='wheel_speeds', enable=1, angle=0, left_speed=400, right_speed=420)


def core_rate(name: str, seconds: float = 20.0, kernels: str = 'auto') -> tuple[float, float]:
    """Measure (steps per wall second, real-time factor) for the world core alone."""
    world = WorldCore(load_layout(layout_path(name)), WorldParams(seed=1, kernels=kernels))
    steps = int(seconds * world.p.sample_rate)
    t0 = time.perf_counter()
    for k in range(steps):
        if k % 3 == 0:
            DRIVE['watchdog'] = (k // 3) & 0xFF
            world.on_record('traction_drive', DRIVE, world.time)
            world.on_record('steering_command', WHEELS if world.layout.vehicle == 'concic2'
                            else STEER, world.time)
        world.step()
    wall = time.perf_counter() - t0
    return steps / wall, seconds / wall


def cpu_seconds(pid: int) -> float:
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def node_cpu(seconds: float) -> float:
    """% of one core used by the world node at time_factor 1 while a probe drives it."""
    env = dict(os.environ, ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', '171'))
    use_localhost_discovery(env)
    exe = str(Path(sys.executable).parent / 'world')
    world = subprocess.Popen([exe, '--ros-args', '-p', 'layout:=straight_track',
                              '-p', 'time_factor:=1.0', '-p', f'duration:={seconds + 2}',
                              '-p', "wait_for_links:=['world:traction_drive']"],
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    probe = subprocess.Popen([sys.executable, str(REPO / 'test' / 'world_probe.py'),
                              str(seconds + 1), '60'], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    time.sleep(2.0)
    c0, t0 = cpu_seconds(world.pid), time.monotonic()
    time.sleep(seconds)
    c1, t1 = cpu_seconds(world.pid), time.monotonic()
    probe.wait(timeout=120)
    world.wait(timeout=60)
    return 100.0 * (c1 - c0) / (t1 - t0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--node-seconds', type=float, default=10.0)
    ap.add_argument('--rounds', type=int, default=2, help='alternated runs of each kernels')
    args = ap.parse_args()
    print('| layout | vehicle | core steps/s, C kernels | real-time factor (340 Hz) | '
          'core steps/s, Python | speed-up |')
    print('|---|---|---|---|---|---|')
    for name in ('straight_track', 'demo_1983', 'sensor_rig', 'tape_1991'):
        best = {'c': (0.0, 0.0), 'python': (0.0, 0.0)}
        for _ in range(args.rounds):
            for kernels in best:
                best[kernels] = max(best[kernels], core_rate(name, kernels=kernels))
        vehicle = load_layout(layout_path(name)).vehicle
        (rate, rtf), (plain, _) = best['c'], best['python']
        print(f'| {name} | {vehicle} | {rate:,.0f} | {rtf:.1f}x | {plain:,.0f} | '
              f'{rate / plain:.2f}x |', flush=True)
    if args.node_seconds > 0:
        print()
        print('| world node at time_factor 1 (340 Hz, /clock every sample) | CPU % of one core |')
        print('|---|---|')
        print(f'| straight_track, driven by a probe | {node_cpu(args.node_seconds):.1f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
