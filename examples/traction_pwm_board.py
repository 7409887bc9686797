"""Example hardware driver: the traction PWM board consuming traction_drive (not installed).

What the 1983 motor controller did with the Traction processor's outputs (thesis 6.3): armature
PWM duty (CTC1), field PWM duty and direction (CTC2, T1-T4), and a trip relay held closed by a
200 ms monostable that the watchdog count retriggers. This driver applies the same rules and, in
place of the power stage, prints what the board would do:

    python examples/traction_pwm_board.py                  # live, against the graph
    python examples/traction_pwm_board.py --bag BAG        # offline, from a recorded run

A record that does not decode is refused (the board keeps its last safe state) and counted.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys

from agv_nodes.records import RecordError, codec

MONOSTABLE = 0.200  # s (thesis B.2.1)


class Board:
    """The board's state machine: PWM registers, field direction, trip relay."""

    def __init__(self) -> None:
        self.last_count: int | None = None
        self.last_change = 0.0
        self.relay_closed = False
        self.rejected = 0
        self.log: list[str] = []

    def drive(self, raw: bytes, now: float) -> None:
        try:
            f = codec()['traction_drive'].decode(raw)
        except RecordError as exc:
            self.rejected += 1
            self.log.append(f'{now:8.3f} refused: {exc}')
            return
        if f['watchdog'] != self.last_count:
            self.last_count, self.last_change = f['watchdog'], now
        self.tick(now, f)

    def tick(self, now: float, f: dict | None = None) -> None:
        closed = now - self.last_change <= MONOSTABLE and bool(f and f['contactor'])
        if closed != self.relay_closed:
            self.relay_closed = closed
            self.log.append(f'{now:8.3f} main contactor {"CLOSED" if closed else "OPEN"}')
        if f and closed:
            arm = f['armature_duty'] if f['armature_enable'] else 0
            field = f['field_duty'] if f['field_enable'] else 0
            way = 'fwd' if f['field_forward'] else 'REV'
            self.log.append(f'{now:8.3f} armature {arm:2d} %  field {field:3d} % {way}')


def replay(bag: Path) -> Board:
    from rosbags.highlevel import AnyReader

    board = Board()
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic.endswith('hw/traction/drive')]
        for conn, stamp, raw in reader.messages(connections=conns):
            board.drive(bytes(reader.deserialize(raw, conn.msgtype).data), stamp * 1e-9)
    return board


def live() -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos

    rclpy.init()
    node = rclpy.create_node('traction_pwm_board')
    # one executor for the run: rclpy.spin_once(node) adds and removes the node each call
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    board = Board()
    now = lambda: node.get_clock().now().nanoseconds * 1e-9  # noqa: E731
    node.create_subscription(UInt8MultiArray, 'hw/traction/drive',
                             lambda m: board.drive(bytes(m.data), now()), qos.RECORD_READER)
    node.create_timer(0.05, lambda: board.tick(now()))
    printed = 0
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
            for line in board.log[printed:]:
                print(line)
            printed = len(board.log)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--bag', type=Path)
    args = ap.parse_args()
    if args.bag:
        board = replay(args.bag)
        changes = [line for line in board.log if 'contactor' in line]
        print('\n'.join(changes))
        print(f'{len(board.log)} board events, {board.rejected} records refused')
    else:
        live()
    return 0


if __name__ == '__main__':
    sys.exit(main())
