"""agv-launch: start the graph one process per node, as `ros2 launch` would on a ROS install.

Each node of config/graph.yaml that the layout's truck has, with the parameter file plus
agv_nodes.graph.parameters (via agv_nodes.graph.supervisor); SIGINT/SIGTERM stop the graph in
order (docs/architecture.md). With --vda5050 also the truck's VDA 5050 bridge, on the broker
--mqtt-url or AGV_MQTT_URL names, else on one the launcher runs in its own process.
"""

import argparse
from pathlib import Path
import sys

from agv_nodes.graph.model import GraphError, load_graph
from agv_nodes.graph.parameters import (
    Options,
    fleet_names,
    parse_fault,
    serial_number,
    truck_graph,
)
from agv_nodes.graph.supervisor import Launch


def build_parser() -> argparse.ArgumentParser:
    """agv-launch arguments."""
    ap = argparse.ArgumentParser(prog='agv-launch', description=__doc__.splitlines()[0])
    ap.add_argument('--graph', type=Path, help='graph description (default config/graph.yaml)')
    ap.add_argument('--params', type=Path, help="ROS parameter file (default: the graph's)")
    ap.add_argument('--namespace', default='', help='e.g. /agv2 for a second truck')
    ap.add_argument('--use-sim-time', choices=('true', 'false'), default='true')
    ap.add_argument('--time-factor', type=float, default=1.0,
                    help='simulated seconds per real second (0 = as fast as possible)')
    ap.add_argument('--record-integrity', choices=('e2e', 'none'), default='e2e')
    ap.add_argument('--world', choices=('sim', 'none'), default='sim',
                    help='none: the hardware topics come from drivers')
    ap.add_argument('--domain-id', type=int, help='ROS_DOMAIN_ID 1-232 (default: a free one)')
    ap.add_argument('--bag', type=Path, help='record every topic into this new bag directory')
    ap.add_argument('--layout', help='world layout (overrides the parameter file)')
    ap.add_argument('--respawn', action='store_true', help='restart nodes that die')
    ap.add_argument('--duration', type=float, help='stop after this many real seconds')
    ap.add_argument('--log-dir', type=Path, help="also write each node's output here")
    ap.add_argument('--fault', action='append', default=[],
                    metavar='RECORD:loss=P,delay=S,corrupt=P',
                    help='lose a fraction of one record, delay it (sim s) or corrupt a fraction '
                    'at its writer, e.g. navigation_status:loss=0.1, traction_link:delay=0.02 '
                    'or traction_status:corrupt=0.5 (corrupt may change at run time: the '
                    "writer's fault_corrupt parameter)")
    ap.add_argument('-p', '--param', action='append', default=[], metavar='NODE:NAME:=VALUE',
                    help='extra parameter for one node, e.g. traction:control:=closed_loop')
    ap.add_argument('--realtime', type=int, default=0, metavar='PRIORITY',
                    help='run the sensor-to-traction chain (the `realtime` nodes of the graph) '
                    'at this SCHED_FIFO priority, 1-99; needs a time factor > 0 and the right '
                    'to (root or CAP_SYS_NICE); default 0: the normal scheduler')
    ap.add_argument('--vda5050', action='store_true',
                    help='also start the vda5050_bridge node: a VDA 5050 master drives the truck')
    ap.add_argument('--mqtt-url', metavar='URL',
                    help="the bridge's MQTT broker, mqtt[s]://host[:port] (default: "
                    'AGV_MQTT_URL, else mosquitto (amqtt where it is not installed) the '
                    'launcher runs itself, ending with it)')
    ap.add_argument('--serial-number', default='', metavar='S',
                    help="the truck's VDA 5050 serialNumber (default: the namespace without "
                    'slashes, or agv1)')
    ap.add_argument('--trucks', type=int, default=0, metavar='N',
                    help='a fleet: N trucks on one simulated floor, each graph in namespace '
                    '/agvK (the world and recorder shared); with --vda5050 a bridge per truck')
    ap.add_argument('--set-down', action='append', default=[], metavar='MARKER',
                    help="with --trucks: the stop marker truck k is set down at, once per "
                    "truck in order (default: the layout's parking places)")
    ap.add_argument('--external-master', action='store_true',
                    help='with --trucks N --vda5050: no dispatcher; the bridges wait for a VDA '
                    '5050 master of your own (e.g. openTCS) on the broker')
    ap.add_argument('--foxglove', type=int, nargs='?', const=8765, default=None, metavar='PORT',
                    help='also start live_view: a Foxglove WebSocket on 127.0.0.1:PORT (default '
                    '8765) with the floor, the trucks, their frames and decoded records')
    return ap


def options_from(args: argparse.Namespace) -> Options:
    """Options from parsed arguments."""
    extra: dict[str, list[str]] = {}
    for item in args.param:
        node, sep, rest = item.partition(':')
        if not sep or ':=' not in rest:
            raise GraphError(f'-p {item!r}: expected NODE:NAME:=VALUE')
        extra.setdefault(node, []).append(rest)
    options = Options(graph=args.graph, params=args.params, namespace=args.namespace,
                      use_sim_time=args.use_sim_time == 'true', time_factor=args.time_factor,
                      record_integrity=args.record_integrity, world=args.world, extra=extra,
                      domain_id=args.domain_id, bag=args.bag, respawn=args.respawn,
                      layout=args.layout, log_dir=args.log_dir, realtime=args.realtime,
                      vda5050=args.vda5050, mqtt_url=args.mqtt_url,
                      serial_number=args.serial_number, trucks=args.trucks,
                      set_down=args.set_down, external_master=args.external_master,
                      foxglove=args.foxglove)
    graph = truck_graph(load_graph(args.graph), options)
    options.faults = dict(parse_fault(text, graph) for text in args.fault)
    return options


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-launch."""
    args = build_parser().parse_args(argv)
    try:
        launch = Launch(options_from(args))
        launch.claim()  # a graph already on its domain and namespace: refused, one line
    except GraphError as exc:
        print(f'agv-launch: {exc}', file=sys.stderr)
        return 2
    print(f'agv-launch: graph {launch.graph.name}, ROS_DOMAIN_ID={launch.domain}, '
          f'{len(launch.units())} processes'
          + (f', {args.trucks} trucks on one floor' if args.trucks else ''), flush=True)
    if launch.mqtt_url:
        where = (f'{launch.broker.name}; ends with agv-launch' if launch.broker else
                 'from --mqtt-url' if args.mqtt_url is not None else 'from AGV_MQTT_URL')
        trucks = ', '.join(fleet_names(launch.o)) or serial_number(launch.o)
        print(f'agv-launch: VDA 5050 bridge {trucks} on MQTT broker '
              f'{launch.mqtt_url} ({where})', flush=True)
    if args.foxglove is not None:
        print(f'agv-launch: live view on ws://127.0.0.1:{args.foxglove} (Foxglove: Open '
              'connection, Foxglove WebSocket)', flush=True)
    return launch.run(args.duration)


if __name__ == '__main__':
    sys.exit(main())
