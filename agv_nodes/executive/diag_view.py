"""agv-diag: the maintenance display in a terminal - a live table of /diagnostics.

One row per sub-system (the executive's view) and per node's record inputs (`<node>/inputs`):
level, reason, rate, age and rejects; `--detail NAME` adds one sub-system's 32 bytes in and out
(hex and decoded), the "key in the sub-system number" display of thesis 8.2.2. Rows from every
publisher are merged by name; `--once` prints one table and exits.
"""

import argparse
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import SingleThreadedExecutor

from agv_nodes import qos

LEVELS = {0: 'OK', 1: 'WARN', 2: 'ERROR', 3: 'STALE'}
COLOURS = {0: '\033[32m', 1: '\033[33m', 2: '\033[31m', 3: '\033[35m'}


def level_of(status) -> int:
    """DiagnosticStatus.level is a bytes object in rclpy."""
    return status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)


def label(status) -> str:
    """Return a row's name: the status name without its 'agv/' prefix (e.g. traction/inputs)."""
    return status.name.split('/', 1)[1] if status.name.startswith('agv/') else status.hardware_id


class Merged:
    """The latest status of each name, from every /diagnostics publisher."""

    def __init__(self) -> None:
        self.by_name: dict = {}
        self.fresh = False

    def __call__(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            self.by_name[st.name] = st
        self.fresh = True

    def array(self) -> DiagnosticArray:
        """Every status so far, sorted by name."""
        return DiagnosticArray(status=[self.by_name[k] for k in sorted(self.by_name)])


def render(msg: DiagnosticArray, detail: str | None = None, colour: bool = True) -> str:
    """Return the table for one DiagnosticArray."""
    lines = [f'{"sub-system":20s} {"level":6s} {"rate Hz":>8s} {"age s":>7s} {"rejects":>8s}  '
             'reason']
    for st in msg.status:
        values = {kv.key: kv.value for kv in st.values}
        lvl = level_of(st)
        name = LEVELS.get(lvl, str(lvl))
        if colour:
            name = f'{COLOURS.get(lvl, "")}{name:6s}\033[0m'
        lines.append(f'{label(st):20s} {name:6s} {values.get("rate (Hz)", "-"):>8s} '
                     f'{values.get("age (s)", "-"):>7s} {values.get("rejected", "-"):>8s}  '
                     f'{st.message}')
        if detail and detail in (st.hardware_id, label(st)):
            lines += [f'    {key:18s} {values[key]}' for key in ('in (hex)', 'in', 'out (hex)',
                      'out', 'rejects by reason', 'last rejection') if key in values]
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-diag."""
    ap = argparse.ArgumentParser(prog='agv-diag', description=__doc__.splitlines()[0])
    ap.add_argument('--detail', help='sub-system whose 32 bytes to show')
    ap.add_argument('--once', action='store_true', help='print one table and exit')
    ap.add_argument('--timeout', type=float, default=30.0, help='with --once: give up after')
    args, ros_args = ap.parse_known_args(argv)
    rclpy.init(args=['agv-diag', *ros_args])
    node = rclpy.create_node('agv_diag')
    executor = SingleThreadedExecutor()  # once, not rclpy.spin_once(node) per turn
    executor.add_node(node)
    got = Merged()
    node.create_subscription(DiagnosticArray, '/diagnostics', got, qos.EVENTS)
    code = 0
    try:
        if args.once:
            deadline = time.monotonic() + args.timeout
            while not got.fresh and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.1)
            end = time.monotonic() + 1.5  # the other publishers' rows (1 Hz each)
            while got.fresh and time.monotonic() < end:
                executor.spin_once(timeout_sec=0.1)
            if not got.fresh:
                print('agv-diag: no /diagnostics received', file=sys.stderr)
                code = 1
            else:
                print(render(got.array(), args.detail, colour=False))
        else:
            while rclpy.ok():
                executor.spin_once(timeout_sec=0.2)
                if got.fresh:
                    sys.stdout.write('\033[2J\033[H' + render(got.array(), args.detail) + '\n')
                    sys.stdout.flush()
                    got.fresh = False
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == '__main__':
    sys.exit(main())
