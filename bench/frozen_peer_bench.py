"""One writer, two reliable readers in processes of their own, one reader frozen (SIGSTOP).

Usage: frozen_peer_bench.py SECONDS DEPTH (results: bench/results/frozen_peer.md). The writer
sends 16-byte strings at 340 Hz on four topics (the ADC snapshot's rate) for SECONDS with the
frozen reader stopped, then prints one JSON line: how many rounds were due at that rate, how
many it sent (a publish held up by the transport sends fewer), the longest round of four
publishes, and what the live reader received. The environment (ROS_DOMAIN_ID, the Fast DDS
profile) is the caller's. Plain rclpy, none of agv_nodes: what is measured is the transport.
"""

import json
import signal
import subprocess
import sys
import time

RATE = 340.0
TOPICS = 4

READER = r"""
import sys, time
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('frozen_peer_' + sys.argv[1])
qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(sys.argv[2]),
                 reliability=ReliabilityPolicy.RELIABLE)
seen = {'count': 0, 'gap': 0.0, 'last': 0.0}
def on(msg):
    now = time.monotonic()
    if msg.data == 'start':
        seen.update(count=0, gap=0.0)
    elif msg.data == 'end':
        print(f'{seen["count"]} {seen["gap"]:.4f}', flush=True)
    else:
        seen['count'] += 1
        seen['gap'] = max(seen['gap'], now - seen['last']) if seen['count'] > 1 else 0.0
    seen['last'] = now
for i in range(int(sys.argv[3])):
    node.create_subscription(String, f'frozen_peer/t{i}', on if i == 0 else (lambda m: None), qos)
print('ready', flush=True)
rclpy.spin(node)
"""


def main() -> None:
    """Run the writer; print what it sent and the live reader received as JSON."""
    seconds, depth = float(sys.argv[1]), int(sys.argv[2])
    readers = {name: subprocess.Popen([sys.executable, '-c', READER, name, str(depth),
                                       str(TOPICS)], stdout=subprocess.PIPE, text=True)
               for name in ('frozen', 'live')}
    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node('frozen_peer_writer')
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                     reliability=ReliabilityPolicy.RELIABLE)
    pubs = [node.create_publisher(String, f'frozen_peer/t{i}', qos) for i in range(TOPICS)]
    try:
        for proc in readers.values():
            assert proc.stdout.readline().strip() == 'ready'
        deadline = time.monotonic() + 30
        while any(p.get_subscription_count() < 2 for p in pubs):  # both matched, every topic
            assert time.monotonic() < deadline, 'readers not matched within 30 s'
            rclpy.spin_once(node, timeout_sec=0.05)
        time.sleep(1.0)  # the readers' side of the match too
        pubs[0].publish(String(data='start'))
        readers['frozen'].send_signal(signal.SIGSTOP)
        sent, worst, start = 0, 0.0, time.monotonic()
        due = start
        while time.monotonic() - start < seconds:
            began = time.monotonic()
            for pub in pubs:
                pub.publish(String(data='x' * 16))
            worst = max(worst, time.monotonic() - began)
            sent += 1
            due += 1 / RATE
            time.sleep(max(0.0, due - time.monotonic()))
        pubs[0].publish(String(data='end'))
        count, gap = readers['live'].stdout.readline().split()
        print(json.dumps({'due': round(seconds * RATE), 'sent': sent, 'received': int(count),
                          'worst_gap': float(gap), 'worst_publish': round(worst, 4)}))
    finally:
        for proc in readers.values():
            proc.kill()
            proc.wait(timeout=10)
        node.destroy_node()
        rclpy.shutdown()


if __name__ == '__main__':
    main()
