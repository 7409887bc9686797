"""What one subscription costs a node process: the floor under each node's CPU.

A publisher process sends /clock (or, with `--message record`, a 16-byte record as a
std_msgs/UInt8MultiArray) at RATE Hz; a subscriber process takes it with an empty callback, in
each variant below, and its CPU (all threads: Python and Fast DDS) is read from /proc over
SECONDS. Every graph node takes a /clock like this (113 Hz at clock_every 3) plus its records;
position_sensor takes 340 ADC snapshots a second on top.

Run: .venv/bin/python bench/rclpy_bench.py [--rate 113] [--seconds 20] [--message record]
     [--variants events,events_raw]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
import subprocess
import sys
import time

from agv_nodes.discovery import use_localhost_discovery
from agv_nodes.graph.supervisor import claim_domain

VARIANTS = {
    'events': 'EventsExecutor, one reliable /clock reader (a node under ClockTimers)',
    'events_raw': 'EventsExecutor, the same reader with raw=True (no message conversion)',
    'events_two': "EventsExecutor, two readers (ClockTimers plus rclpy's TimeSource, as before)",
    'single': 'SingleThreadedExecutor, one reader',
}

PUBLISHER = """
import sys, time
import rclpy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import UInt8MultiArray
from agv_nodes import qos
rclpy.init()
node = rclpy.create_node('rclpy_bench_clock')
record = sys.argv[2] == 'record'
pub = node.create_publisher(UInt8MultiArray if record else Clock,
                            'hw/position_sensor/adc' if record else '/clock', qos.STREAM_WRITER)
rate, t0, k = float(sys.argv[1]), time.monotonic(), 0
while rclpy.ok():
    k += 1
    if record:
        msg = UInt8MultiArray(data=bytes(16))
    else:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(int(k / rate * 1e9), 1_000_000_000)
    pub.publish(msg)
    time.sleep(max(0.0, t0 + k / rate - time.monotonic()))
"""

SUBSCRIBER = """
import sys
import rclpy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import UInt8MultiArray
from agv_nodes import qos
from agv_nodes.node_process import make_executor
variant, record = sys.argv[1], sys.argv[2] == 'record'
rclpy.init()
node = rclpy.create_node('rclpy_bench_reader')
readers = 2 if variant == 'events_two' else 1
for _ in range(readers):
    node.create_subscription(UInt8MultiArray if record else Clock,
                             'hw/position_sensor/adc' if record else '/clock', lambda msg: None,
                             qos.STREAM_READER if record else qos.CLOCK_READER,
                             raw=variant == 'events_raw')
executor = make_executor('single' if variant == 'single' else 'events')
executor.add_node(node)
while rclpy.ok():
    executor.spin_once(timeout_sec=0.1)
"""


def cpu_seconds(pid: int) -> float:
    """User + system CPU of a process, s."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rate', type=float, default=113.3)
    ap.add_argument('--seconds', type=float, default=20.0)
    ap.add_argument('--message', choices=('clock', 'record'), default='clock',
                    help='what is sent: /clock (rosgraph_msgs/Clock) or a 16-byte record '
                    '(std_msgs/UInt8MultiArray on hw/position_sensor/adc)')
    ap.add_argument('--variants', default=','.join(VARIANTS))
    args = ap.parse_args()
    domain, _lock = claim_domain()
    env = {**os.environ, 'ROS_DOMAIN_ID': str(domain)}
    use_localhost_discovery(env)
    print(f'{args.message} at {args.rate:g} Hz, {args.seconds:g} s per variant, '
          f'ROS_DOMAIN_ID={domain}\n')
    print('| subscriber | CPU (% of one core) | per message (us) |\n|---|---|---|')
    for variant in args.variants.split(','):
        label = VARIANTS[variant]
        quiet = {'env': env, 'stderr': subprocess.DEVNULL}  # (SIGTERM tracebacks)
        pub = subprocess.Popen([sys.executable, '-c', PUBLISHER, str(args.rate), args.message],
                               **quiet)
        sub = subprocess.Popen([sys.executable, '-c', SUBSCRIBER, variant, args.message], **quiet)
        try:
            time.sleep(4.0)  # discovery and start-up
            c0, t0 = cpu_seconds(sub.pid), time.monotonic()
            time.sleep(args.seconds)
            used = (cpu_seconds(sub.pid) - c0) / (time.monotonic() - t0)
        finally:
            for proc in (sub, pub):
                proc.terminate()
                proc.wait(10)
        print(f'| {label} | {100 * used:.1f} | {1e6 * used / args.rate:.0f} |', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
