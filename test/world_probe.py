"""A test peer for the world node.

It drives the truck (traction_drive + steering_command at 100 Hz) and counts what the world
publishes until /clock passes `seconds`, then prints JSON.
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
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

    def on_adc(msg: UInt8MultiArray) -> None:
        c.decode('adc_snapshot', bytes(msg.data))
        state['adc'] += 1

    def on_clock(msg: Clock) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        if state['first_clock'] is None and t > 0:
            state['first_clock'] = t
        state['clock'] = t

    def on_odo(msg: UInt8MultiArray) -> None:
        state['speed'] = c.decode('wheel_odometry', bytes(msg.data))['left_speed']

    def tick() -> None:
        state['watchdog'] = (state['watchdog'] + 1) & 0xFF
        drive.publish(dict(armature_duty=duty, field_duty=98, armature_enable=1, field_enable=1,
                           field_forward=1, contactor=1, watchdog=state['watchdog']))
        steer.publish(dict(mode='angle', enable=1, angle=0, left_speed=0, right_speed=0))

    node.create_subscription(UInt8MultiArray, 'hw/position_sensor/adc', on_adc, reliable)
    node.create_subscription(Clock, '/clock', on_clock, reliable)
    node.create_subscription(UInt8MultiArray, 'hw/wheel_odometry', on_odo, reliable)
    node.create_timer(0.01, tick)
    deadline = time.monotonic() + 120
    while rclpy.ok() and state['clock'] < seconds and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    print(json.dumps(state), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
