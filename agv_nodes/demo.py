"""agv-demo: the closed-loop demonstration (the README's first command).

Starts a truck's whole graph (one process per node over real DDS, sim time) with the recorder,
sends its demonstration programme on comms/task, shows the reports, stops the graph, writes the
report and prints a summary table. `--truck electruk` (default): the 1983 tug in the demo_1983
room, thesis 7.2 tasks 1-7 and the fig 3.1 transfer. `--truck concic2`: the 1991 camera truck on
the signs_1991 tape, legs through every road sign with scripted turns and a reverse leg;
`--truck concic2 --layout FILE` on a tape layout of one's own, one leg to the tape's end.
`--quick` runs the CI variant of either.
"""

import argparse
from collections.abc import Callable, Iterable
import json
from pathlib import Path
import sys
import time
from typing import Any, TypedDict

from agv_nodes.graph.model import GraphError
from agv_nodes.graph.parameters import Options, wait_links
from agv_nodes.graph.supervisor import Launch
from agv_nodes.harness import CONCIC2_PROGRAMME, CONCIC2_QUICK, DEMO_PROGRAMME
from agv_nodes.sim_progress import CLOCK_LINK

# truck -> (layout, programme, quick programme)
TRUCKS = {'electruk': ('demo_1983', DEMO_PROGRAMME, DEMO_PROGRAMME[:2]),
          'concic2': ('signs_1991', CONCIC2_PROGRAMME, CONCIC2_QUICK)}
# A tape layout of one's own has no programme written for it: a leg along the tape from where the
# truck stands to the tape's end, straight on at every junction, is one any tape layout can run.
OWN_TAPE_PROGRAMME = ('tape',)
STATUS_REPLY = 'comms: status:'


class RunState(TypedDict):
    """What the demo's callbacks gather while the programme runs."""

    sim: float  # s, from the truck's pose stamps
    results: dict[int, tuple[str, str, float]]  # task -> (result, its report line, sim time)
    reports: list[tuple[float, str]]  # (sim time, report line)
    lines: list[str]  # every report line, for the handshake


def comms_handshake(spin_once: Callable[[], None], send: Callable[[str], None],
                    reports: list[str], timeout: float = 60.0,
                    alive: Callable[[], bool] = lambda: True) -> None:
    """Ask communications `status` until it answers on comms/report (why: docs/tasks.md)."""
    deadline, asked = time.monotonic() + timeout, 0.0
    while not any(line.startswith(STATUS_REPLY) for line in reports):
        if not alive() or time.monotonic() > deadline:
            raise RuntimeError('communications did not answer a status query on comms/task')
        if time.monotonic() - asked > 0.25:
            send('status')
            asked = time.monotonic()
        spin_once()


def silent_links(links: list[str], accepted: dict[str, dict[str, int]],
                 quiet: Iterable[str] = ()) -> list[str]:
    """Return the 'reader:record' links whose reader has accepted nothing yet (`accepted`).

    Records in `quiet` carry nothing on this layout (Launch.silent_records) and are left out.

    `accepted` (node -> record -> count) is from the readers' `/diagnostics` inputs rows, which
    list only the records a node decodes; a node not heard from yet has every link silent.
    """
    silent = []
    for link in links:
        node, sep, record = link.partition(':')
        if not sep or '>' in node or record == CLOCK_LINK or record in quiet:
            continue  # a writer's end ('node>record:N'), or /clock (not a record)
        row = accepted.get(node)
        if row is None or row.get(record, 1 if node == 'world' else 0) == 0:
            silent.append(link)
    return silent


def accepted_counts(values: dict[str, str]) -> dict[str, int]:
    """Record -> records accepted, from one inputs row's values (`'<record> accepted'`)."""
    return {key[:-len(' accepted')]: int(value) for key, value in values.items()
            if key.endswith(' accepted') and value.isdigit()}


def inputs_accepted(msg: Any) -> dict[str, dict[str, int]]:
    """Node -> record -> accepted, from the `agv[/ns]/<node>/inputs` rows of a DiagnosticArray."""
    out: dict[str, dict[str, int]] = {}
    for status in msg.status:
        parts = status.name.split('/')
        if len(parts) < 3 or parts[0] != 'agv' or parts[-1] != 'inputs':
            continue
        out[parts[-2]] = accepted_counts({kv.key: kv.value for kv in status.values})
    return out


def programme(args: argparse.Namespace) -> tuple[str, list[str]]:
    """Return the layout (a name or a file) and the tasks of the run `args` asks for."""
    layout, tasks, quick = TRUCKS[args.truck]
    if getattr(args, 'layout', None):  # a tape layout of one's own (main checked its vehicle)
        layout, tasks, quick = args.layout, OWN_TAPE_PROGRAMME, OWN_TAPE_PROGRAMME
    return layout, list(quick if args.quick else tasks)


def run(args: argparse.Namespace) -> int:
    """Launch, drive the programme, stop, report; exit status."""
    out = Path(args.out or f'runs/demo-{time.strftime("%Y%m%d-%H%M%S")}')
    out.mkdir(parents=True, exist_ok=True)
    layout, tasks = programme(args)
    try:
        launch = Launch(Options(time_factor=args.time_factor, bag=out / 'bag', quiet=True,
                                log_dir=out / 'logs', domain_id=args.domain_id, layout=layout,
                                foxglove=args.foxglove))
    except GraphError as exc:
        print(f'agv-demo: {exc}', file=sys.stderr)
        return 2
    launch.join()
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    import rclpy  # after the domain is chosen: this process joins the graph
    from std_msgs.msg import String

    from agv_nodes import qos
    from agv_nodes.node_process import make_executor

    print(f'agv-demo: {args.truck}, {len(tasks)} tasks on {layout}; {len(launch.specs())} '
          f'processes, ROS_DOMAIN_ID={launch.domain}, time_factor {args.time_factor:g}; '
          f'output in {out}')
    rclpy.init()
    node = rclpy.create_node('demo')
    # One executor for the run, not rclpy.spin_once(node), which adds the node to the global
    # executor and takes it out on every call: 14.5 % of a core at 116 Hz, against 6.2 %.
    executor = make_executor('events')
    executor.add_node(node)
    state: RunState = {'sim': 0.0, 'results': {}, 'reports': [], 'lines': []}

    def on_pose(msg: PoseStamped) -> None:
        state['sim'] = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    def on_report(msg: String) -> None:
        state['reports'].append((state['sim'], line := msg.data))
        state['lines'].append(line)
        if line.startswith(STATUS_REPLY):
            return
        print(f'  {state["sim"]:7.1f} s  {line}', flush=True)
        words = line.split()
        if len(words) > 2 and words[0] == 'task' and words[1].isdigit():
            for final in ('completed', 'FAILED', 'rejected'):
                if f': {final}' in line:
                    state['results'][int(words[1])] = (final.lower(), line, state['sim'])

    # Sim time from the truck's pose (50 Hz, stamped with sim time), not /clock: 116 Hz to one
    # more reader cost the world's publisher and this process more than progress lines need.
    node.create_subscription(PoseStamped, 'world/pose', on_pose, qos.STREAM_READER)
    node.create_subscription(String, 'comms/report', on_report, qos.EVENTS)
    accepted: dict[str, dict[str, int]] = {}
    node.create_subscription(DiagnosticArray, '/diagnostics',
                             lambda msg: accepted.update(inputs_accepted(msg)), qos.EVENTS)
    task_pub = node.create_publisher(String, 'comms/task', qos.EVENTS)
    wall0 = time.monotonic()
    launch.start()
    code = 0
    try:
        deadline = time.monotonic() + 120
        while not launch.moving.is_set() or task_pub.get_subscription_count() == 0:
            executor.spin_once(timeout_sec=0.1)
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError(f'the graph did not come up (see the logs in {out / "logs"})')
        comms_handshake(lambda: executor.spin_once(timeout_sec=0.05),
                        lambda text: task_pub.publish(String(data=text)), state['lines'],
                        alive=lambda: not launch.poll())
        # Every link has carried records before the programme goes: the world moved only once
        # both ends of each had matched, but a run whose navigation still had no sensor status
        # at its first task must fail here, naming the link, and not as a task's `sensor lost`.
        # (The CONCIC-II has no navigation; the same holds for its camera route following.)
        links = wait_links(launch.graph, recording=True)
        deadline = time.monotonic() + 60
        while silent := silent_links(links, accepted, launch.silent_records):
            if launch.poll() or time.monotonic() > deadline:
                raise RuntimeError(f'no record yet on {", ".join(silent)} (the readers\' '
                                   '/diagnostics inputs rows)')
            executor.spin_once(timeout_sec=0.1)
        print(f'agv-demo: graph up in {time.monotonic() - wall0:.1f} s, every link carrying '
              f'records at {state["sim"]:.1f} s; sending the programme')
        moving_wall, sim0, cpu0 = time.monotonic(), state['sim'], launch.cpu_seconds()
        for text in tasks:
            task_pub.publish(String(data=text))
        limit = args.sim_limit
        while len(state['results']) < len(tasks):
            executor.spin_once(timeout_sec=0.1)
            if launch.poll():
                raise RuntimeError(f'node(s) died: {", ".join(launch.failed)}')
            if state['sim'] - sim0 > limit:
                raise RuntimeError(f'programme not finished after {limit:.0f} simulated s')
        sim_elapsed, wall_elapsed = state['sim'] - sim0, time.monotonic() - moving_wall
        cpu = process_cpu(cpu0, launch.cpu_seconds(), sim_elapsed, wall_elapsed)
        # A second for the recorder to take what was sent last (the final report), or the bag
        # may lack it.
        settle = time.monotonic() + 1.0
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.1)
    except (RuntimeError, KeyboardInterrupt) as exc:
        print(f'agv-demo: {exc}', file=sys.stderr)
        code, sim_elapsed, wall_elapsed = 1, state['sim'], time.monotonic() - wall0
        cpu = {}
    finally:
        executor.remove_node(node)
        node.destroy_node()
        rclpy.try_shutdown()
        launch.stop()
    failed = [t for t, (s, _l, _t) in state['results'].items() if s != 'completed']
    code = code or (1 if failed else 0)
    summary = {'tasks': [{'task': i + 1, 'text': text,
                          'result': state['results'].get(i + 1, ('not finished',))[0],
                          'sim_time': state['results'].get(i + 1, (None, None, None))[2]}
                         for i, text in enumerate(tasks)],
               'sim_seconds': sim_elapsed, 'wall_seconds': wall_elapsed,
               'real_time_factor': sim_elapsed / wall_elapsed if wall_elapsed else 0.0,
               'truck': args.truck, 'layout': layout,
               'bag': str(out / 'bag'), 'processes': len(launch.specs()),
               'node_exits': launch.exits, 'cpu': cpu}
    (out / 'demo.json').write_text(json.dumps(summary, indent=2))
    report = None
    if not args.no_report and (out / 'bag').exists():
        if args.truck == 'concic2':
            from agv_nodes.camera_report import make_camera_report

            report = make_camera_report(out / 'bag', out / 'report', layout)
        else:
            from agv_nodes.report import make_report

            report = make_report(out / 'bag', out / 'report')
    print_summary(summary, report, out)
    return code


def process_cpu(before: dict[str, float], after: dict[str, float], sim: float,
                wall: float) -> dict[str, dict[str, float]]:
    """Each process's CPU over the programme: ms per simulated s and % of a core.

    At time factor 0 the world runs as fast as the graph keeps up, so the process nearest 100 %
    of a core (or the two cores shared out) is what holds the graph back.
    """
    if sim <= 0 or wall <= 0:
        return {}
    used = {name: after[name] - before[name] for name in after if name in before}
    return {name: {'ms_per_sim_s': 1000.0 * spent / sim, 'percent_of_core': 100.0 * spent / wall}
            for name, spent in sorted(used.items(), key=lambda kv: -kv[1])}


def print_summary(summary: dict, report: dict | None, out: Path) -> None:
    """Print the closing table."""
    print('\n| task | result | sim time (s) |\n|---|---|---|')
    for t in summary['tasks']:
        when = f'{t["sim_time"]:.1f}' if t['sim_time'] is not None else '-'
        print(f'| {t["task"]}: {t["text"]} | {t["result"]} | {when} |')
    if report and 'stops' in report and report['stops'] and 'marker' in report['stops'][0]:
        print('\n| stop | marker | error (mm, + = past the centre) | speed before (mm/s) |\n'
              '|---|---|---|---|')
        for i, s in enumerate(report['stops'], 1):
            print(f'| {i} | {s["marker"]} | {s["error_mm"]:+d} | {s["speed_mm_s"]} |')
    if report and 'legs' in report:
        print('\n| leg | direction | distance (m) | junctions | lateral rms / max (mm) |\n'
              '|---|---|---|---|---|')
        for leg in report['legs']:
            rms, top = leg['lateral_rms_mm'], leg['lateral_max_mm']
            error = '-' if rms is None else f'{rms:.1f} / {top}'
            print(f'| {leg["leg"]} | {leg.get("direction", "-")} | {leg["distance_m"]:.2f} | '
                  f'{leg["junctions"]} | {error} |')
        print(f'\nroad signs met: {len(report["signs"])}; stops: {len(report["stops"])}')
    if report and 'faults' in report:
        print(f'\nfaults: {"; ".join(report["faults"] or ["none"])}')
    if summary.get('cpu'):
        print('\n| process | CPU, ms per simulated s | % of a core |\n|---|---|---|')
        for name, c in summary['cpu'].items():
            print(f'| {name} | {c["ms_per_sim_s"]:.1f} | {c["percent_of_core"]:.1f} |')
    print(f'\nsimulated {summary["sim_seconds"]:.1f} s in {summary["wall_seconds"]:.1f} s wall '
          f'= real-time factor {summary["real_time_factor"]:.2f} '
          f'({summary["processes"]} processes)')
    print(f'bag: {summary["bag"]}')
    if report:
        print(f'report: {out / "report" / "summary.md"} (plots: {out / "report"}/*.png)')


def own_layout_problem(file: str, truck: str) -> str | None:
    """Return why layout `file` is no room for `truck` (one line naming both), or None."""
    from agv_nodes.world.layout import layout_path, load_layout
    from agv_nodes.world.tape_layout import LayoutError

    try:
        vehicle = load_layout(layout_path(file)).vehicle
    except (LayoutError, OSError) as exc:
        return f'--layout {file}: {exc}'
    if vehicle != truck:
        return (f'--layout {file}: a layout for the {vehicle}, not the {truck} (--truck '
                f'{truck} runs a tape layout; --fleet runs an electruk one)')
    return None


def own_layout_warnings(file: str) -> list[str]:
    """Return the layout check's warnings of a tape layout: bends tighter than the truck follows.

    The run goes on (the truck may read a road sign on the bend, or lose the tape there).
    """
    from agv_nodes.world.layout import layout_path, load_layout
    from agv_nodes.world.tape_check import tight_bends

    return tight_bends(load_layout(layout_path(file)))


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-demo."""
    ap = argparse.ArgumentParser(prog='agv-demo', description=__doc__.splitlines()[0])
    ap.add_argument('--truck', choices=sorted(TRUCKS), default='electruk',
                    help='electruk: the 1983 wire-guided tug (default); concic2: the 1991 camera '
                    'truck on taped floor')
    ap.add_argument('--quick', action='store_true', help='the short CI variant of the programme')
    # 0 is safe because the world paces itself on the slowest node (world/pacing.py): unpaced,
    # a fixed 1.25x saturates the 2-core reference machine and markers are seen late (stops at
    # +54/+70 mm) or missed; paced, the programme runs at ~1.2x with stops as in lock step.
    ap.add_argument('--time-factor', type=float, default=0.0,
                    help='simulated seconds per real second the world aims for (default 0: as '
                    'fast as the slowest node keeps up)')
    ap.add_argument('--out', help='output directory (default runs/demo-<time>)')
    ap.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID (default: a free one)')
    ap.add_argument('--sim-limit', type=float, default=1500.0,
                    help='give up after this many simulated seconds')
    ap.add_argument('--no-report', action='store_true')
    ap.add_argument('--foxglove', type=int, nargs='?', const=8765, default=None, metavar='PORT',
                    help='watch it live: a Foxglove WebSocket on 127.0.0.1:PORT (default 8765; '
                    'live_view, docs/architecture.md "Watching a run")')
    ap.add_argument('--fleet', type=int, default=0, metavar='N',
                    help='N 1983 trucks on one floor, directed by the dispatcher over VDA 5050 '
                    '(MQTT) through two loads going round (agv_nodes.fleet.fleet_demo)')
    ap.add_argument('--external-master', action='store_true',
                    help='with --fleet: no dispatcher; the trucks wait for a VDA 5050 master '
                    'of your own on the printed broker until Ctrl-C')
    ap.add_argument('--mqtt-url', help='with --fleet: a broker of your own, mqtt://host[:port] '
                    '(default: AGV_MQTT_URL, else one the launcher runs: mosquitto, or amqtt)')
    ap.add_argument('--layout', help='with --fleet: the floor (default demo_1983, room for '
                    'three trucks; fleet_1983 parks eight); with --truck concic2: a tape layout '
                    "(name or file), one leg to the tape's end")
    ap.add_argument('--transfers', type=int, metavar='K',
                    help='with --fleet: transfers in the programme (default 8, --quick 2)')
    args = ap.parse_args(argv)
    if args.layout and args.truck == 'concic2' and not args.fleet:
        if problem := own_layout_problem(args.layout, 'concic2'):
            print(f'agv-demo: {problem}', file=sys.stderr)
            return 2
        for line in own_layout_warnings(args.layout):
            print(f'agv-demo: warning: {line}', file=sys.stderr)
        return run(args)
    if args.fleet or args.external_master or args.mqtt_url or args.transfers is not None \
            or args.layout:
        if not args.fleet:
            ap.error('--external-master, --mqtt-url, --transfers and --layout are for a fleet: '
                     'add --fleet N (or --layout with --truck concic2: a tape layout)')
        if args.transfers is not None and args.transfers < 1:
            ap.error(f'--transfers {args.transfers}: at least 1')
        if args.truck != 'electruk':
            ap.error('--fleet runs the 1983 truck (--truck electruk)')
        from agv_nodes.fleet.fleet_demo import run as run_fleet

        return run_fleet(args)
    return run(args)


if __name__ == '__main__':
    sys.exit(main())
