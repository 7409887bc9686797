"""A test peer for the world node.

It drives the truck (traction_drive + steering_command at 100 Hz) and counts the ADC snapshots
the world sent before the /clock sample that reached `seconds`, then prints JSON. Counted by the
time each was sent (DDS source timestamps, all from the world's one clock), not by the /clock
the probe had seen on arrival: a probe short of CPU drains its /clock queue faster than its ADC
queue (one sample of each per executor turn, ADC three times as frequent), and what was still
queued when its /clock passed `seconds` would go uncounted.
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import UInt8MultiArray

from agv_nodes.records import codec
from agv_nodes.ros_ports import RecordPublisher


def main() -> int:
    seconds, duty = float(sys.argv[1]), int(sys.argv[2])
    rclpy.init()
    node = Node('world_probe')
    # one executor for the run: rclpy.spin_once(node) adds and removes the node each call
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    c = codec()
    drive = RecordPublisher(node, c['traction_drive'])
    steer = RecordPublisher(node, c['steering_command'])
    state = {'adc': 0, 'clock': 0.0, 'first_clock': None, 'speed': 0, 'watchdog': 0,
             'events': 0}
    reliable = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
    # every sample kept until taken: the count must not depend on how far behind the probe runs
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    adc_sent: list[int] = []
    mark = {'sent': None}  # source timestamp of the first /clock sample at or past `seconds`

    def on_adc(msg: UInt8MultiArray, info: dict) -> None:
        c.decode('adc_snapshot', bytes(msg.data))
        adc_sent.append(info['source_timestamp'])

    def on_clock(msg: Clock, info: dict) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        if state['first_clock'] is None and t > 0:
            state['first_clock'] = t
        if mark['sent'] is None:
            state['clock'] = t
            if t >= seconds:
                mark['sent'] = info['source_timestamp']

    def counted() -> bool:
        """Return True once an ADC sent after the mark arrived: every earlier one is in (FIFO)."""
        return mark['sent'] is not None and bool(adc_sent) and adc_sent[-1] > mark['sent']

    def on_odo(msg: UInt8MultiArray) -> None:
        state['speed'] = c.decode('wheel_odometry', bytes(msg.data))['left_speed']

    def tick() -> None:
        state['watchdog'] = (state['watchdog'] + 1) & 0xFF
        drive.publish(dict(armature_duty=duty, field_duty=98, armature_enable=1, field_enable=1,
                           field_forward=1, contactor=1, watchdog=state['watchdog']))
        steer.publish(dict(mode='angle', enable=1, angle=0, left_speed=0, right_speed=0))

    node.create_subscription(UInt8MultiArray, 'hw/position_sensor/adc', on_adc, keep_all)
    node.create_subscription(Clock, '/clock', on_clock, keep_all)
    node.create_subscription(UInt8MultiArray, 'hw/wheel_odometry', on_odo, reliable)
    node.create_timer(0.01, tick)
    deadline = time.monotonic() + 120
    while rclpy.ok() and not counted() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    if mark['sent'] is not None:
        state['adc'] = sum(1 for sent in adc_sent if sent < mark['sent'])
    print(json.dumps(state), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
