"""What the launch sets for each node on top of the parameter file.

The one source for agv-launch and launch/agv_demo.launch.py (test_launch_file.py compares them):
sim time, record integrity, faults, the simulation channel, links to wait for, priority.
"""

from collections.abc import Iterable
from dataclasses import dataclass, field
import os
from pathlib import Path

import yaml

from agv_nodes.graph.model import Graph, GraphError, NodeSpec
from agv_nodes.records import codec
from agv_nodes.settings import ParameterFileError, parameter_file_values
from agv_nodes.sim_progress import CLOCK_LINK as CLOCK
from agv_nodes.sim_progress import LINK as PROGRESS
from agv_nodes.world.layout import (
    Layout,
    LayoutError,
    layout_parameters,
    layout_path,
    load_layout,
)
from agv_nodes.world.settings import WorldNodeSettings


@dataclass
class Options:
    """Everything agv-launch can be told (and the launch file's arguments)."""

    graph: Path | None = None
    params: Path | None = None
    namespace: str = ''
    use_sim_time: bool = True
    time_factor: float = 1.0
    record_integrity: str = 'e2e'
    world: str = 'sim'
    domain_id: int | None = None
    bag: Path | None = None
    respawn: bool = False
    layout: str | None = None
    extra: dict[str, list[str]] = field(default_factory=dict)  # node -> extra -p args
    # record -> {'loss': fraction, 'delay': s, 'seed': n}: injected at its writer (--fault)
    faults: dict[str, dict[str, float]] = field(default_factory=dict)
    quiet: bool = False
    log_dir: Path | None = None
    realtime: int = 0  # SCHED_FIFO priority of the graph's `realtime` nodes (0 = off)
    vda5050: bool = False  # also start the `bridge` node: the truck's link to a master control
    mqtt_url: str | None = None  # the bridge's broker (None: AGV_MQTT_URL, else an embedded one)
    serial_number: str = ''  # the bridge's VDA 5050 serialNumber ('': from the namespace)
    trucks: int = 0  # a fleet on one floor: N trucks in namespaces agv1..agvN (0: one truck)
    set_down: list[str] = field(default_factory=list)  # each truck's stop marker ([]: parking)
    external_master: bool = False  # a fleet's bridges wait for a master of the user's own
    foxglove: int | None = None  # the live view's Foxglove WebSocket port (None: no live view)


def record_readers(graph: Graph, world: bool, recording: bool) -> dict[str, int]:
    """Each record whose writer and a reader run -> its running readers (+1 for the recorder)."""
    running = {n.name for n in graph.nodes if n.role == 'node' or (n.role == 'world' and world)}
    counts = {s.name: sum(r in running for r in s.readers) for s in codec()
              if s.kind != 'ground_truth' and s.writer in running}
    return {name: n + recording for name, n in counts.items() if n}


def paced_nodes(graph: Graph, options: Options) -> list[str]:
    """Return the world's `pace_nodes`: every sub-system node on sim time, none on wall time."""
    return sorted(n.name for n in graph.nodes if n.role == 'node' and options.use_sim_time)


def wait_links(graph: Graph, recording: bool = False, paced: Iterable[str] = ()) -> list[str]:
    """Return the world's `wait_for_links`: both ends of every link of the graph.

    'reader:record' for each reader of each record (both ends launched); 'writer>record:N', the
    writer has matched all N readers (record_readers); 'node>progress:1' for each paced node;
    on sim time 'world>clock:N', /clock matched by the paced nodes and the recorder, and
    'recorder:clock', the recorder's /clock reader matched. An
    unmatched end loses what is sent (docs/architecture.md, "Start-up"): navigation would call a
    silent sensor lost, and the world would pace on a node it cannot hear.
    """
    running = {n.name for n in graph.nodes if n.role in ('node', 'world')}
    progress = {n.name for n in graph.nodes if n.role == 'node'}  # the world has no progress
    links = {f'{r}:{s.name}' for s in codec() if s.kind != 'ground_truth'
             and s.writer in running for r in s.readers if r in running}
    for name, n in record_readers(graph, 'world' in running, recording).items():
        links.add(f'{codec()[name].writer}>{name}:{n}')
    links.update(f'{node}>{PROGRESS}:1' for node in paced if node in progress)
    clock_readers = len([node for node in paced if node in progress]) + recording
    if paced and clock_readers:  # on sim time: every /clock reaches the nodes and the bag
        links.add(f'world>{CLOCK}:{clock_readers}')
        if recording:
            links.add(f'recorder:{CLOCK}')
    return sorted(links)


def parse_fault(text: str, graph: Graph) -> tuple[str, dict[str, float]]:
    """'RECORD:loss=0.1,delay=0.02' -> (record, {'loss': 0.1, 'delay': 0.02}); also corrupt=P."""
    record, _, spec = text.partition(':')
    c = codec()
    writers = {n.name for n in graph.nodes if n.role == 'node'}
    if record not in c or c[record].writer not in writers:
        raise GraphError(f'--fault {text!r}: {record!r} is not a record a node of the graph '
                         f'writes ({", ".join(s.name for s in c if s.writer in writers)})')
    out: dict[str, float] = {}
    for item in filter(None, spec.split(',')):
        key, _, value = item.partition('=')
        try:
            number = float(value)
        except ValueError:
            number = -1.0
        if key not in ('loss', 'delay', 'corrupt', 'seed') or number < 0 or \
                (key in ('loss', 'corrupt') and number > 1):
            raise GraphError(f'--fault {text!r}: {item!r} (expected loss=0..1, delay=S, '
                             'corrupt=0..1, seed=N)')
        out[key] = number
    if not out:
        raise GraphError(f'--fault {text!r}: nothing to inject (loss=..., delay=..., corrupt=...)')
    return record, out


def layout_name(graph: Graph, options: Options) -> str:
    """Return the layout the world loads: --layout, else the parameter file's, else its default."""
    if options.layout:
        return options.layout
    try:
        shared, own = parameter_file_values(options.params or graph.parameters, 'world')
    except ParameterFileError as exc:
        raise GraphError(str(exc)) from None
    return str(own.get('layout', shared.get('layout', WorldNodeSettings().layout)))


def launch_layout(graph: Graph, options: Options) -> Layout:
    """Load the layout the world loads (a GraphError naming it if it cannot be used)."""
    name = layout_name(graph, options)
    try:
        return load_layout(layout_path(name))
    except (LayoutError, FileNotFoundError) as exc:
        raise GraphError(f'layout {name!r}: {exc}') from None


def truck_graph(graph: Graph, options: Options) -> Graph:
    """Return the graph of the truck the layout names (the CONCIC-II has fewer nodes)."""
    return graph.for_truck(launch_layout(graph, options).vehicle)


def silent_records(graph: Graph, options: Options) -> set[str]:
    """Return the records whose links match but carry nothing on this layout's truck.

    The world writes `guide_wire` only from wires (the CONCIC-II's camera route following does
    not read it) and `drive_status` only for the CONCIC-II (its safety PAL; the 1983 tug has
    none); a start-up check that waits for every link to carry a record leaves these out.
    """
    layout = launch_layout(graph, options)
    wires = any(path.width == 0.0 for path in layout.paths.values())
    return ({'guide_wire'} if not wires else set()) | \
        ({'drive_status'} if layout.vehicle != 'concic2' else set())


def from_layout(graph: Graph, options: Options) -> dict[str, dict[str, object]]:
    """Return what the layout sets in the nodes (layout_parameters, as the harness applies it)."""
    return layout_parameters(launch_layout(graph, options))


def node_parameters(graph: Graph, spec: NodeSpec, options: Options,
                    ready_file: Path | None = None) -> dict[str, object]:
    """Return what the launch sets on one node over the file (`ready_file`: the world's signal)."""
    out: dict[str, object] = {'use_sim_time': options.use_sim_time}
    if spec.role == 'node':
        out.update(from_layout(graph, options).get(spec.name, {}))
        out['record_integrity'] = options.record_integrity
        # the simulation channel exists only with a simulated world on sim time: hardware
        # has no world to pace, and on wall time nothing holds the clock back
        out['sim_progress'] = options.world == 'sim' and options.use_sim_time
        if options.trucks:  # the floor's world, in the root namespace, writes /clock
            out['clock_writer'] = '/world'
        for record, fault in options.faults.items():
            if codec()[record].writer == spec.name:
                out.update(fault_record=record, fault_loss=fault.get('loss', 0.0),
                           fault_delay=fault.get('delay', 0.0),
                           fault_corrupt=fault.get('corrupt', 0.0),
                           fault_seed=int(fault.get('seed', 1)))
    if spec.role == 'world':
        out.update(from_layout(graph, options).get('world', {}))  # e.g. the rear camera
        paced = paced_nodes(graph, options)
        out.update(time_factor=float(options.time_factor), publish_clock=options.use_sim_time,
                   wait_for_links=wait_links(graph, options.bag is not None, paced),
                   pace_nodes=paced)
        if ready_file is not None:
            out['ready_file'] = str(ready_file)
        if options.layout:
            out['layout'] = options.layout
    if spec.role == 'recorder':  # its decoded records judged as the nodes judge them
        out.update(bag=str(options.bag), layout=layout_name(graph, options),
                   record_integrity=options.record_integrity)
    if spec.role == 'master':  # the fleet: where each truck is set down, and parks
        places = fleet_places(graph, options)
        out.update(layout=layout_name(graph, options), trucks=fleet_names(options),
                   positions=places, parking=places, mqtt_url=options.mqtt_url or '')
    if spec.role == 'viewer':  # the live view draws the world's floor and every truck
        out.update(port=int(options.foxglove or 0), layout=layout_name(graph, options),
                   trucks=fleet_names(options) if options.trucks else [''])
    if spec.role == 'bridge':  # its orders name the markers of the layout the world runs
        out.update(layout=layout_name(graph, options), serial_number=serial_number(options),
                   mqtt_url=options.mqtt_url or '')
    return out


def override_parameters(graph: Graph, spec: NodeSpec, options: Options,
                        ready_file: Path | None = None) -> dict[str, object]:
    """node_parameters() plus the node's `-p NAME:=VALUE` extras (values parsed as YAML)."""
    out = node_parameters(graph, spec, options, ready_file)
    for arg in options.extra.get(spec.name, []):
        name, _sep, text = arg.partition(':=')
        try:
            out[name] = yaml.safe_load(text) if text else ''
        except yaml.YAMLError as exc:
            raise GraphError(f'-p {spec.name}:{arg}: value is not YAML ({exc})') from exc
    return out


MAX_TRUCKS = 32


def fleet_names(options: Options) -> list[str]:
    """Return the namespaces (and VDA 5050 serial numbers) of a fleet's trucks: agv1..agvN."""
    return [f'agv{k + 1}' for k in range(options.trucks)]


def fleet_places(graph: Graph, options: Options) -> list[str]:
    """Return 'agvK:MARKER' for each truck: where it is set down (--set-down, else parking)."""
    places = options.set_down or list(launch_layout(graph, options).parking)
    return [f'{name}:{place}' for name, place in zip(fleet_names(options), places, strict=False)]


def check_fleet(graph: Graph, options: Options) -> None:
    """Refuse a --trucks the graph cannot run, naming why (before anything starts)."""
    if options.external_master and not (options.trucks and options.vda5050):
        raise GraphError('--external-master: a master of your own drives a fleet through its '
                         'bridges: add --trucks N --vda5050')
    if not options.trucks:
        if options.set_down:
            raise GraphError('--set-down places the trucks of a fleet: add --trucks N')
        return
    given = {'--namespace': options.namespace, '--serial-number': options.serial_number,
             '--world none': options.world == 'none'}
    for flag, value in given.items():
        if value:
            raise GraphError(f"--trucks {options.trucks} with {flag}: a fleet's trucks are "
                             'agv1..agvN, each in its own namespace, on the simulated floor')
    if not 1 <= options.trucks <= MAX_TRUCKS:
        raise GraphError(f'--trucks {options.trucks}: 1-{MAX_TRUCKS}')
    layout = launch_layout(graph, options)
    name = layout_name(graph, options)
    if layout.vehicle != 'electruk' or layout.kind != 'wire':
        raise GraphError(f'--trucks: layout {name!r} is not a wire layout of the Electruk (a '
                         'fleet runs on one)')
    places = options.set_down or list(layout.parking)
    if len(places) < options.trucks or options.set_down and len(places) != options.trucks:
        where = '--set-down' if options.set_down else f'layout {name!r} parking'
        raise GraphError(f'--trucks {options.trucks}: {where} names {len(places)} stop markers '
                         f'({", ".join(places) or "none"}); each truck needs one')
    stops = {m.name for m in layout.markers if m.kind == 'stop'}
    for place in places:
        if place not in stops:
            raise GraphError(f'--set-down {place}: no stop marker {place!r} in layout {name!r} '
                             f'({", ".join(sorted(stops))})')


def floor_parameters(graph: Graph, spec: NodeSpec, options: Options,
                     ready_file: Path | None = None) -> dict[str, object]:
    """Return the world's override file for a fleet: the floor's node and each truck's world.

    The floor (/world) waits for the links of /clock (every truck's nodes and the recorder
    read it); each truck's world (/agvK/world) for the rest of its truck's links, and paces on
    its truck's nodes (agv_nodes.world.floor).
    """
    common = override_parameters(graph, spec, options, ready_file)
    names = fleet_names(options)
    common.update(trucks=names, set_down=list(options.set_down))
    truck_links, root_links = [], []
    recording = options.bag is not None
    waits = common['wait_for_links']
    if not isinstance(waits, list):  # override_parameters lists them
        raise TypeError(f'wait_for_links: {waits!r} is no list')
    for link in waits:
        node, _, rest = link.partition('>')
        if rest.startswith(f'{CLOCK}:'):  # this truck's readers of /clock, times N trucks
            readers = int(rest.partition(':')[2]) - recording
            root_links.append(f'{node}>{CLOCK}:{readers * len(names) + recording}')
        elif link == f'recorder:{CLOCK}':
            root_links.append(link)
        else:
            truck_links.append(link)
    out: dict[str, object] = {
        '/world': {'ros__parameters': {**common, 'wait_for_links': root_links}}}
    for name in names:
        out[f'/{name}/world'] = {'ros__parameters': {**common, 'wait_for_links': truck_links}}
    return out


class _PlainDumper(yaml.SafeDumper):
    """YAML without anchors and aliases (see parameter_file_text)."""

    def ignore_aliases(self, data: object) -> bool:
        return True


def parameter_file_text(content: dict[str, object]) -> str:
    """Return a ROS parameter file's text: YAML without anchors and aliases.

    rcl's parameter file parser refuses them, and yaml writes them for any list that two
    parameters share (a fleet's floor gives each truck's world the same lists).
    """
    return yaml.dump(content, Dumper=_PlainDumper)


def serial_number(options: Options) -> str:
    """Return the bridge's serialNumber: --serial-number, else the namespace, else 'agv1'.

    One truck per namespace, so the namespace (without its slashes) names the truck to the
    master control as it names it on the ROS graph.
    """
    return options.serial_number or options.namespace.replace('/', '') or 'agv1'


def launched(spec: NodeSpec, options: Options) -> bool:
    """Return True if the launch starts this node of the truck's graph.

    The world is left out for hardware drivers, the recorder when nothing is recorded and the
    bridge unless asked for; the master (the dispatcher) runs only for a fleet whose bridges
    it drives, when no external master is to.
    """
    return not (spec.role == 'world' and options.world == 'none'
                or spec.role == 'recorder' and options.bag is None
                or spec.role == 'bridge' and not options.vda5050
                or spec.role == 'viewer' and options.foxglove is None
                or spec.role == 'master' and not (options.trucks and options.vda5050
                                                  and not options.external_master))


def launch_units(graph: Graph, options: Options) -> list[tuple[str, NodeSpec, str]]:
    """Return the processes a launch starts, in order: (label, node, namespace).

    `graph` is the truck's (truck_graph). One truck: each launched node once, labelled by its
    name, in the namespace option. A fleet (`trucks`): the recorder and the world once, in the
    root namespace (the world simulates every truck, agv_nodes.world.floor), the other nodes
    once per truck in its namespace, labelled `agvK/name`; the master (the dispatcher) once.
    """
    specs = [n for n in graph.nodes if launched(n, options)]
    if not options.trucks:
        return [(spec.name, spec, options.namespace) for spec in specs]
    shared = ('recorder', 'master', 'world', 'viewer')
    return [(s.name, s, '') for s in specs if s.role == 'recorder'] + [
        (f'{truck}/{s.name}', s, f'/{truck}') for truck in fleet_names(options)
        for s in specs if s.role not in shared] + [
        (s.name, s, '') for s in specs if s.role in ('master', 'world', 'viewer')]


def check_vda5050(graph: Graph, options: Options) -> None:
    """Refuse VDA 5050 options the truck's graph cannot use, naming why (before anything starts).

    `graph` is the truck's (truck_graph): only a truck whose graph has a `bridge` node can be
    driven by a master control.
    """
    if not options.vda5050:
        if options.mqtt_url is not None or options.serial_number:
            given = '--mqtt-url' if options.mqtt_url is not None else '--serial-number'
            raise GraphError(f'{given} is for the VDA 5050 bridge: add --vda5050')
        return
    if not any(n.role == 'bridge' for n in graph.nodes):
        layout = launch_layout(graph, options)
        raise GraphError(f'--vda5050: layout {layout_name(graph, options)!r} drives the '
                         f'{layout.vehicle} truck, whose graph ({graph.file}) has no VDA 5050 '
                         'bridge (its tasks are another language)')
    from agv_nodes.vda5050.topics import topic  # pydantic models: only with --vda5050

    serial = serial_number(options)
    try:  # the rule for a topic level (VDA 5050 6.3), as the bridge will apply it
        topic('manufacturer', serial, 'connection')
    except ValueError as exc:
        raise GraphError(f'--serial-number {serial!r}: {exc}') from None


def realtime_priority(spec: NodeSpec, options: Options) -> int:
    """Return a node's SCHED_FIFO priority: `--realtime N` for `realtime` nodes, else 0.

    As a robot's control processes run (each 1983 sub-system had a Z-80 of its own).
    """
    return options.realtime if spec.realtime else 0


def check_realtime(options: Options) -> None:
    """Refuse a --realtime the graph cannot use, naming why (before anything starts)."""
    if not options.realtime:
        return
    if not 1 <= options.realtime <= 99:
        raise GraphError(f'--realtime {options.realtime}: a SCHED_FIFO priority is 1-99')
    if options.time_factor <= 0:
        raise GraphError(f'--realtime {options.realtime} needs a time factor > 0: at time '
                         'factor 0 the world never sleeps, and at real-time priority it would '
                         'hold a core against every other node')
    policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    try:  # try it on this thread, then back: a graph must not start half real-time
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(options.realtime))
        os.sched_setscheduler(0, policy, param)
    except PermissionError:
        raise GraphError(f'--realtime {options.realtime}: this user may not use SCHED_FIFO '
                         '(it needs CAP_SYS_NICE, or an rtprio limit in '
                         '/etc/security/limits.conf)') from None
