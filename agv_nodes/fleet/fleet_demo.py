"""agv-demo --fleet N: N 1983 trucks on one floor, directed by the dispatcher over VDA 5050.

The whole fleet over DDS and MQTT, as a user would run it: `agv-launch --trucks N --vda5050`
(one world simulating every truck, each truck's graph in its namespace /agvK with its VDA 5050
bridge, an MQTT broker of its own, a recorder) and the dispatcher node as the trucks' master, on
demo_1983 (three trucks at most) or `--layout fleet_1983` (eight). The demo gives the
dispatcher transport orders as text on `fleet/transport`: loads going round
(agv_nodes.world.fleet_floor.programme_loads: on demo_1983 A between W0 and W2 and B between
W1 and W3, on fleet_1983 one per truck), the next transfer of a load sent when its last one is
done (fleet/report). It watches each truck's world events for collisions and ends with a
table: the transfers, each truck's distance, the collisions (there must be none).

With --external-master no dispatcher runs: the bridges wait for a VDA 5050 master of the user's
own (openTCS, or any other) on the broker the demo prints, until Ctrl-C (docs/fleet.md).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
import sys
import time
from typing import Any

from agv_nodes.graph.model import GraphError
from agv_nodes.graph.parameters import Options, fleet_names, launch_layout
from agv_nodes.graph.supervisor import Launch
from agv_nodes.world.fleet_floor import programme_loads

LAYOUT = 'demo_1983'  # the default floor (agv-demo --layout)
TRANSFERS, QUICK_TRANSFERS = 8, 2
STATUS_QUERY = 'status'  # the dispatcher's answer proves both directions of fleet/transport
STEP_KEYS = ('steps', 'step median ms', 'step p99 ms', 'step max ms')  # from its /diagnostics


class TruckView:
    """One truck seen from the demo: its distance, its collisions, its sim time."""

    def __init__(self, node: Any) -> None:
        from geometry_msgs.msg import PoseStamped

        from agv_nodes import qos
        from agv_nodes.records.codec import codec
        from agv_nodes.ros_ports import RecordSubscription

        self.node = node
        self.time = 0.0
        self.distance = 0.0
        self.collisions = 0
        self._last: tuple[float, float] | None = None
        node.create_subscription(PoseStamped, 'world/pose', self._pose, qos.STREAM_READER)
        self._events = RecordSubscription(node, codec()['world_event'], 'e2e', self._event)

    def _pose(self, msg: Any) -> None:
        self.time = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        here = (msg.pose.position.x, msg.pose.position.y)
        if self._last is not None:
            self.distance += math.dist(here, self._last)
        self._last = here

    def _event(self, fields: dict) -> None:
        if fields['event'] == 'collision':
            self.collisions += 1


class Programme:
    """The loads going round: which transfer to send next, and which are done."""

    def __init__(self, transfers: int, loads: dict[str, tuple[str, str]]) -> None:
        self.total = transfers
        self.loads = loads  # each load's two stations, where it is first
        self.where = dict.fromkeys(loads, 0)  # index of the station each load is at
        self.pending: dict[str, str] = {}  # transfer id -> load
        self.sent = 0
        self.done: list[tuple[str, str, float]] = []  # (id, line, sim s)
        self.failed: list[str] = []

    def next_for(self, load: str) -> str | None:
        """Return the next transport text for `load` (None when the programme is all sent)."""
        if self.sent >= self.total:
            return None
        self.sent += 1
        here, there = self.loads[load][self.where[load]], self.loads[load][1 - self.where[load]]
        self.pending[f't{self.sent}'] = load
        return f't{self.sent}: {here} to {there}'

    def on_report(self, line: str, now: float) -> str | None:
        """Take a fleet/report line; return the load whose next transfer is due, if any."""
        ident, _, rest = line.partition(': ')
        if ident not in self.pending:
            return None
        if rest.startswith('done'):
            load = self.pending.pop(ident)
            self.where[load] = 1 - self.where[load]
            self.done.append((ident, line, now))
            return load
        if rest.startswith('failed'):
            self.pending.pop(ident)
            self.failed.append(line)
        return None


def run(args: argparse.Namespace) -> int:
    """Launch the fleet, drive the programme (or wait for an external master), report."""
    out = Path(args.out or f'runs/fleet-{time.strftime("%Y%m%d-%H%M%S")}')
    out.mkdir(parents=True, exist_ok=True)
    layout = args.layout or LAYOUT
    try:
        launch = Launch(Options(time_factor=args.time_factor, bag=out / 'bag', quiet=True,
                                log_dir=out / 'logs', domain_id=args.domain_id, layout=layout,
                                trucks=args.fleet, vda5050=True, mqtt_url=args.mqtt_url,
                                external_master=args.external_master,
                                foxglove=getattr(args, 'foxglove', None)))
        loads = programme_loads(launch_layout(launch.graph, launch.o).stations, args.fleet)
    except (GraphError, ValueError) as exc:
        print(f'agv-demo: {exc}', file=sys.stderr)
        return 2
    launch.join()
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy  # after the domain is chosen: this process joins the graph
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.node_process import make_executor

    names = fleet_names(launch.o)
    print(f'agv-demo: fleet of {args.fleet} on {layout}; {len(launch.units())} processes, '
          f'ROS_DOMAIN_ID={launch.domain}, MQTT {launch.mqtt_url}, time_factor '
          f'{args.time_factor:g}; output in {out}', flush=True)
    rclpy.init()
    executor = make_executor('single')
    node = rclpy.create_node('fleet_demo')
    executor.add_node(node)
    views = {}
    for name in names:
        view_node = rclpy.create_node('fleet_demo', namespace=f'/{name}')
        executor.add_node(view_node)
        views[name] = TruckView(view_node)
    programme = Programme(args.transfers or (QUICK_TRANSFERS if args.quick else TRANSFERS),
                          loads)
    lines: list[str] = []
    transport = node.create_publisher(String, 'fleet/transport', qos.EVENTS)

    def send(text: str) -> None:
        transport.publish(String(data=text))
        print(f'  {now():7.1f} s  sent {text!r}', flush=True)

    def now() -> float:
        return max(v.time for v in views.values())

    def on_report(msg: String) -> None:
        lines.append(msg.data)
        if msg.data.startswith(STATUS_QUERY):
            return
        print(f'  {now():7.1f} s  {msg.data}', flush=True)
        if (load := programme.on_report(msg.data, now())) and (text := programme.next_for(load)):
            send(text)

    node.create_subscription(String, 'fleet/report', on_report, qos.EVENTS)
    dispatcher: dict[str, str] = {}  # its /diagnostics row: counts and step times

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.endswith('/dispatcher/fleet'):
                dispatcher.update({kv.key: kv.value for kv in status.values})

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, qos.EVENTS)
    wall0 = time.monotonic()
    launch.start()
    code, sim0, moving_wall = 0, 0.0, wall0
    try:
        deadline = time.monotonic() + 180
        while not launch.moving.is_set():
            executor.spin_once(timeout_sec=0.1)
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError(f'the fleet did not come up (see the logs in {out / "logs"})')
        if args.external_master:
            print(f'agv-demo: {", ".join(names)} wait for a VDA 5050 master on '
                  f'{launch.mqtt_url} (topics uagv/v2/agv_nodes/<agvK>/...); Ctrl-C ends')
            while not launch.poll():
                executor.spin_once(timeout_sec=0.2)
            raise RuntimeError(f'node(s) died: {", ".join(launch.failed)}')
        asked = 0.0
        while not any(line.startswith(STATUS_QUERY) for line in lines):
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError('the dispatcher did not answer a status query')
            if time.monotonic() - asked > 0.25:
                transport.publish(String(data=STATUS_QUERY))
                asked = time.monotonic()
            executor.spin_once(timeout_sec=0.05)
        sim0, moving_wall = now(), time.monotonic()
        print(f'agv-demo: fleet up in {moving_wall - wall0:.1f} s; sending the programme')
        for load in loads:
            if text := programme.next_for(load):
                send(text)
        while len(programme.done) + len(programme.failed) < programme.total:
            executor.spin_once(timeout_sec=0.1)
            if launch.poll():
                raise RuntimeError(f'node(s) died: {", ".join(launch.failed)}')
            if programme.failed:
                raise RuntimeError(f'a transfer failed: {programme.failed[0]}')
            if now() - sim0 > args.sim_limit:
                raise RuntimeError(f'programme not finished after {args.sim_limit:.0f} '
                                   'simulated s')
        settle = time.monotonic() + 1.5  # the recorder takes the last reports, a last row
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.1)
    except (RuntimeError, KeyboardInterrupt) as exc:
        if not isinstance(exc, KeyboardInterrupt):
            print(f'agv-demo: {exc}', file=sys.stderr)
            code = 1
    finally:
        sim_elapsed, wall_elapsed = now() - sim0, time.monotonic() - moving_wall
        for view in views.values():
            executor.remove_node(view.node)
            view.node.destroy_node()
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
        launch.stop()
    collisions = sum(v.collisions for v in views.values())
    code = code or (1 if collisions else 0)
    summary = {'trucks': args.fleet, 'layout': layout, 'transfers': programme.total,
               'done': [{'id': i, 'line': line, 'sim_time': t} for i, line, t in
                        programme.done],
               'failed': programme.failed, 'collisions': collisions,
               'distance_m': {n: round(v.distance, 2) for n, v in views.items()},
               'sim_seconds': sim_elapsed, 'wall_seconds': wall_elapsed,
               'real_time_factor': sim_elapsed / wall_elapsed if wall_elapsed > 0 else 0.0,
               'dispatcher': {k: dispatcher[k] for k in STEP_KEYS if k in dispatcher},
               'bag': str(out / 'bag'), 'processes': len(launch.units()),
               'node_exits': launch.exits}
    (out / 'fleet.json').write_text(json.dumps(summary, indent=2))
    if not args.external_master:
        print_summary(summary)
    return code


def print_summary(summary: dict) -> None:
    """Print the closing table."""
    print('\n| transfer | result | sim time (s) |\n|---|---|---|')
    for t in summary['done']:
        print(f'| {t["id"]} | {t["line"]} | {t["sim_time"]:.1f} |')
    for line in summary['failed']:
        print(f'| - | {line} | - |')
    print('\n| truck | distance (m) |\n|---|---|')
    for name, metres in summary['distance_m'].items():
        print(f'| {name} | {metres:.1f} |')
    print(f'\n{len(summary["done"])} of {summary["transfers"]} transfers done; collisions: '
          f'{summary["collisions"]}; simulated {summary["sim_seconds"]:.1f} s in '
          f'{summary["wall_seconds"]:.1f} s wall = real-time factor '
          f'{summary["real_time_factor"]:.2f} ({summary["processes"]} processes)')
    steps = summary['dispatcher']
    if steps:
        print(f'dispatcher: {steps["steps"]} steps, median {steps["step median ms"]} ms, p99 '
              f'{steps["step p99 ms"]} ms, max {steps["step max ms"]} ms')
    print(f'bag: {summary["bag"]}')
