"""The camera truck's route_following node over DDS: its CPU with both cameras at 20 frames/s.

Runs the CONCIC-II graph (agv-launch --layout tape_1991: world, route_following, executive,
communications, each its own process; sim time at the given time factor) with the truck
following the circle under the task `tape`, once per setting of route_following's `cameras`.
After a settling pause it samples each process's CPU from /proc over the measured span, and
counts, from a reader of its own, the frames on hw/camera/front and hw/camera/rear and the sim
seconds on /clock. CPU per sim second is the process's CPU time over the simulated seconds;
% of a core is that at real time (one sim second per second). The whole node counts here: rclpy,
DDS, the image messages' decoding and the route-following core (bench/route_cpu_bench.py
times the core alone). Goal: under 5 % of a core at 20 frames/s per camera.

Run: .venv/bin/python bench/camera_node_cpu_bench.py [--seconds 30] [--out FILE]
"""

from __future__ import annotations

import argparse
from pathlib import Path
import sys
import time

from graph_bench import cpu_seconds

from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch

GOAL = 5.0  # % of a core
CLOCKS = {'sim': 'sim time: /clock at 113 Hz', 'wall': 'wall time: no /clock (a real truck)'}


WHY = """
Where the time goes. The route-following core itself takes 1.1 % of a core with the leading
camera and 1.7 % with both (bench/results/route_cpu_bench.md); the rest is rclpy's cost per
event, about 0.15-0.25 ms for each message taken or sent and each timer callback
(bench/results/rclpy_bench.md). Route following handles some 550 events a second: its 100 Hz
loop and the steering_command it sends each pass, 100 wheel_odometry records, 40 frames, the
20 Hz route_command, drive_status and route_status, and on sim time 113 /clock steps; the
communications node, which does next to nothing between tasks, shows the floor of a node
process. Sending steering_command only on a change of the wheel speeds and as a 30 ms
keep-alive took one point off and let the CONCIC-II's 60 ms steering watchdog trip on wall
time under this load, so the node still sends it every pass. The goal needs fewer events (a
40 ms cycle, as the thesis's computer ran, with 25 Hz odometry) or a cheaper rclpy path.
A py-spy profile of the node (lead camera, sim time, 20 s at 200 samples/s: `py-spy record -p PID
-d 20 -r 200 -f raw`) agrees: of its 12.8 % of a core, 36 % is the executor's wait and take in C,
27 % the C write of Publisher.publish (0.29 ms a record, the records already serialized: Fast DDS's
write; the 100 Hz steering_command is nearly all of them), 10 % the frames' analysis, 10 % taking
and decoding records, 5 % the clock.
"""


def measure(cameras: str, seconds: float, time_factor: float, sim_time: bool = True
            ) -> tuple[dict[str, float], str]:
    """Run the graph with route_following's `cameras`: the measured figures, the task's state.

    The state is 'running', or the first report of the task's failure (the truck stopped).
    """
    launch = Launch(Options(time_factor=time_factor, layout='tape_1991', quiet=True,
                            use_sim_time=sim_time,
                            extra={'route_following': [f'cameras:={cameras}']}))
    launch.join()
    import rclpy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.demo import comms_handshake

    rclpy.init()
    node = rclpy.create_node('camera_node_cpu_bench')
    frames = {'front': 0, 'rear': 0}
    sim = [0.0]

    def count(name: str):  # noqa: ANN202
        def cb(_msg: Image) -> None:
            frames[name] += 1
        return cb

    for name in frames:
        node.create_subscription(Image, f'hw/camera/{name}', count(name), qos.STREAM_READER)
    node.create_subscription(Clock, '/clock', lambda m: sim.__setitem__(
        0, m.clock.sec + m.clock.nanosec * 1e-9), qos.CLOCK_READER)
    pub = node.create_publisher(String, 'comms/task', qos.EVENTS)
    lines: list[str] = []
    node.create_subscription(String, 'comms/report', lambda m: lines.append(m.data), qos.EVENTS)
    try:
        launch.start()
        while not launch.moving.is_set() or pub.get_subscription_count() == 0:
            rclpy.spin_once(node, timeout_sec=0.1)
        comms_handshake(lambda: rclpy.spin_once(node, timeout_sec=0.05),
                        lambda text: pub.publish(String(data=text)), lines)
        pub.publish(String(data='tape'))
        end = time.monotonic() + 5.0  # set off and settle on the tape
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        c0 = {n: cpu_seconds(p.pid) for n, p in launch.procs.items()}
        f0, s0, t0 = dict(frames), sim[0], time.monotonic()
        while time.monotonic() < t0 + seconds:
            rclpy.spin_once(node, timeout_sec=0.05)
        c1 = {n: cpu_seconds(p.pid) for n, p in launch.procs.items()}
        wall = time.monotonic() - t0
        span = sim[0] - s0 if sim_time else wall
        f1 = dict(frames)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        launch.stop()
    out = {'sim': span, 'wall': wall}
    out.update({f'{n} fps': (f1[n] - f0[n]) / span for n in frames})
    out.update({f'{n} ms': 1000 * (c1[n] - c0[n]) / span for n in c0})
    failed = [line for line in lines if 'fail' in line.lower()]
    return out, (failed[0] if failed else 'running')


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seconds', type=float, default=30.0, help='real seconds measured per run')
    ap.add_argument('--time-factor', type=float, default=1.0)
    ap.add_argument('--out', type=Path, default=None, help='also write the table here')
    args = ap.parse_args(argv)
    command = ('.venv/bin/python bench/camera_node_cpu_bench.py '
               + ' '.join(sys.argv[1:] if argv is None else argv)).strip()
    runs = {(cameras, clock): measure(cameras, args.seconds, args.time_factor, clock == 'sim')
            for clock in ('sim', 'wall') for cameras in ('lead', 'both')}
    procs = sorted(k[:-3] for k in runs['lead', 'sim'][0] if k.endswith(' ms'))
    rows = []
    for (cameras, clock), (r, task) in runs.items():
        rf = r['route_following ms'] / 10.0  # ms per sim s -> % of a core at real time
        rows.append(f'| {CLOCKS[clock]} | {cameras} | {r["sim"]:.1f} | '
                    f'{r["sim"] / r["wall"]:.2f} | '
                    f'{r["front fps"]:.1f} / {r["rear fps"]:.1f} | '
                    f'{r["route_following ms"]:.1f} | {rf:.2f} | '
                    f'{"yes" if rf < GOAL else "**no**"} | {task} | '
                    + ' | '.join(f'{r[p + " ms"] / 10.0:.1f}' for p in procs
                                 if p != 'route_following') + ' |')
    others = [p for p in procs if p != 'route_following']
    text = '\n'.join([
        "# The camera truck's route_following node: CPU over DDS", '',
        f'Command: `{command}`', '', ' '.join(__doc__.split('\n\n')[1].split()), '',
        '| clock | cameras | s measured | real-time factor | frames/s front / rear | '
        'route_following CPU (ms per sim s) | route_following (% of a core) | under 5 % | task | '
        + ' | '.join(f'{p} (% of a core)' for p in others) + ' |',
        '|' + '---|' * (9 + len(others)), *rows, '', ' '.join(WHY.split()), '',
        'Measured on a 2-core machine.']) + '\n'
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
