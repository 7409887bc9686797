"""Example hardware driver: the marker-sensor board publishing adc_snapshot (not installed).

The Mk 1 board converts eight photodiodes with the IREDs on, then eight with them off (ADC0809,
8-bit), 340 times a second. This driver publishes each such 16-byte sample on
hw/position_sensor/adc, where the position_sensor node expects it, so the graph can run with
world:=none. The position_sensor node takes that record only from its named writer, so it is
told this board's node name:
`-p "record_writers:=['adc_snapshot=marker_sensor_board']"` (docs/hardware.md).

    python examples/marker_sensor_board.py --serial /dev/ttyUSB0      # 16 bytes per sample
    python examples/marker_sensor_board.py --bag runs/demo-*/bag      # replay a recorded run
    python examples/marker_sensor_board.py --bag BAG --start 8 --end 11  # a stretch of it

A serial frame is 16 raw bytes (lit 1-8, dark 1-8); a frame that does not decode is counted
and dropped, never published. Replay keeps the recorded spacing of the samples.
"""

from __future__ import annotations

import argparse
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor

from agv_nodes.records import RecordError, codec
from agv_nodes.ros_ports import RecordPublisher


def frames_from_serial(port: str, baud: int):
    """16-byte frames from a serial line (needs pyserial)."""
    try:
        import serial  # noqa: PLC0415 - optional dependency of this example only
    except ImportError:
        sys.exit('marker_sensor_board: --serial needs pyserial (pip install pyserial)')
    with serial.Serial(port, baud, timeout=1.0) as line:
        while True:
            frame = line.read(16)
            if len(frame) == 16:
                yield None, frame


def frames_from_bag(bag: str, topic_suffix: str = 'hw/position_sensor/adc'):
    """(time, 16 bytes) of every recorded ADC snapshot, in order."""
    from pathlib import Path

    from rosbags.highlevel import AnyReader

    with AnyReader([Path(bag)]) as reader:
        conns = [c for c in reader.connections if c.topic.endswith(topic_suffix)]
        for conn, stamp, raw in reader.messages(connections=conns):
            yield stamp * 1e-9, bytes(reader.deserialize(raw, conn.msgtype).data)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument('--serial')
    src.add_argument('--bag')
    ap.add_argument('--baud', type=int, default=115200)
    ap.add_argument('--start', type=float, default=0.0, help='replay from this recorded time, s')
    ap.add_argument('--end', type=float, default=float('inf'),
                    help='replay up to this recorded time, s')
    ap.add_argument('--reader-timeout', type=float, default=10.0,
                    help='replay: seconds to wait for a reader before sending (0: do not wait)')
    args = ap.parse_args()
    schema = codec()['adc_snapshot']
    rclpy.init()
    node = rclpy.create_node('marker_sensor_board')
    # one executor for the run: rclpy.spin_once(node) adds and removes the node each call
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    pub = RecordPublisher(node, schema)
    frames = frames_from_serial(args.serial, args.baud) if args.serial else \
        frames_from_bag(args.bag)
    rejected = sent = 0
    start_wall = start_rec = None
    if args.bag:  # a replay starts once the position sensor listens (what went before is lost)
        deadline = time.monotonic() + args.reader_timeout
        while pub.subscription_count == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
    try:
        for stamp, frame in frames:
            if stamp is not None and stamp < args.start:
                continue
            if stamp is not None and stamp > args.end:
                break
            try:
                fields = schema.decode(frame)
            except RecordError as exc:
                rejected += 1
                node.get_logger().warn(f'frame dropped: {exc}', throttle_duration_sec=1.0)
                continue
            if stamp is not None:  # replay at the recorded pace
                if start_wall is None:
                    start_wall, start_rec = time.monotonic(), stamp
                delay = (stamp - start_rec) - (time.monotonic() - start_wall)
                if delay > 0:
                    time.sleep(delay)
            pub.publish(fields)
            sent += 1
            executor.spin_once(timeout_sec=0.0)
    except KeyboardInterrupt:
        pass
    finally:
        print(f'marker_sensor_board: {sent} snapshots published, {rejected} frames dropped')
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
