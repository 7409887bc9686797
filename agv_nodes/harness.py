"""Lock-step harness: the world core and any set of node cores stepped together without DDS.

Deterministic and seeded; records go through `RecordWriter` and `RecordReader` with the schemas'
ports, as in the graph (docs/architecture.md, "The lock-step harness"). A node core has:

    node: str                     # its name in msg_schemas (writer / readers)
    period: float | None          # seconds between tick() calls; None = only on_record
    on_record(record, fields, now) -> {record: fields} | None   # an accepted input
    tick(now) -> {record: fields} | None                         # its timer

Records a core returns are delivered at once within the world sample, as the 1983 boards'
pigeon-holes were read on the next loop: every reader of a record takes it before the records
they return go out, each in turn and on to its readers; timers run after it on the simulated
clock.
"""

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import math
from pathlib import Path
import random
from typing import TYPE_CHECKING, Any, Protocol
import warnings

from agv_nodes.harness_timers import fire_timers
from agv_nodes.records.codec import Codec
from agv_nodes.records.codec import codec as installed_codec
from agv_nodes.records.ports import RecordReader, RecordWriter
from agv_nodes.world.core import WorldCore

if TYPE_CHECKING:  # imported where used: `truck` builds the cores
    from agv_nodes.communications.core import CommunicationsCore

# Records sent in answer to records, nested, before the harness calls it a loop (a real chain
# is a few deep: a sensor record, the navigation's answer, traction's).
MAX_CHAIN = 100


def run_for(stepped: Any, seconds: float, until: Callable[[], bool] | None = None) -> bool:
    """Step `stepped` for `seconds` of simulated time, or until `until()` is true (returns it).

    `stepped` has step() and now: a harness, a fleet of them, a fleet with its master.
    """
    end = stepped.now + seconds
    while stepped.now < end - 1e-12:
        stepped.step()
        if until is not None and until():
            return True
    return False


class NodeCore(Protocol):
    """What the harness (and the generic node wrapper) needs from a core."""

    node: str
    period: float | None
    p: Any  # its settings: each core's own settings class

    def __init__(self, params: Any = None) -> None: ...

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None: ...

    def tick(self, now: float) -> dict | None: ...


@dataclass
class Link:
    """Fault injection on one record topic (drop some records, delay the rest)."""

    drop: float = 0.0  # probability a record is lost
    delay: float = 0.0  # seconds every record is held back


@dataclass
class _Member:
    core: NodeCore
    readers: dict[str, RecordReader] = field(default_factory=dict)
    writers: dict[str, RecordWriter] = field(default_factory=dict)
    next_tick: float = 0.0
    next_supervise: float = 0.0


def _answer(out: list | None, m: _Member, outputs: dict) -> list:
    """Return `out` (a new list for None) with a member's answer to a record appended."""
    out = [] if out is None else out
    out.append((m, outputs))
    return out


class Harness:
    """Steps a WorldCore and node cores in lock step; see the module docstring."""

    # the truck's cores by node name, set by `truck` (each core's own class: callers pick one
    # by name and use its own interface, e.g. communications' on_task)
    cores: dict[str, Any]

    def __init__(self, world: WorldCore, cores: Iterable[NodeCore], *, integrity: str = 'e2e',
                 codec: Codec | None = None, seed: int = 0) -> None:
        self.world = world
        self.codec = codec or installed_codec()
        self.integrity = integrity
        self.members: list[_Member] = []
        self.rng = random.Random(seed)
        self.links: dict[str, Link] = {}
        self.taps: list[Callable[[str, bytes, float], None]] = []
        self.events: list[dict[str, Any]] = []
        self.frames: dict[str, Any] = {}
        self._delayed: list[tuple[float, str, bytes, str]] = []
        self._bumper = False
        self.world_writers = {s.name: RecordWriter(s, 'none') for s in self.codec
                              if s.writer == 'world'}
        self.world_readers = {s.name: RecordReader(s, 'none') for s in self.codec
                              if 'world' in s.readers}
        # record -> (world's reader, [(member, reader)], decode), built on first delivery after
        # an add() (`_route`)
        self._routes: dict[str, tuple] = {}
        self._ns_of: float | None = None  # the sim time _now_ns (ns) is of
        self._now_ns = 0
        self._depth = 0  # records delivered in answer to records, nested
        self._timers_due = -math.inf  # no node timer is due before this sim time
        for core in cores:
            self.add(core)

    def add(self, core: NodeCore) -> None:
        """Plug a node core in (its ports come from the schemas)."""
        reads, writes = self.codec.for_node(core.node)
        mode = {s.name: self.integrity if s.protected else 'none' for s in (*reads, *writes)}
        self.members.append(_Member(core, {s.name: RecordReader(s, mode[s.name]) for s in reads},
                                    {s.name: RecordWriter(s, mode[s.name]) for s in writes},
                                    self.world.time))
        self._routes.clear()
        self._timers_due = -math.inf

    def restart(self, node: str) -> None:
        """Start `node` afresh, as a respawned process: new core state, counters from 0.

        Its readers see a new writer, as the graph's WriterCheck tells them of a new GID, and
        take it up at once (`resync`).
        """
        m = next(m for m in self.members if m.core.node == node)
        m.core = type(m.core)(m.core.p)
        m.writers = {name: RecordWriter(w.schema, w.integrity) for name, w in m.writers.items()}
        for record in m.writers:
            for other in self.members:
                if record in other.readers:
                    other.readers[record].resync()
        m.next_tick = m.next_supervise = self.now
        self._timers_due = -math.inf
        if (cores := getattr(self, 'cores', None)) is not None:
            cores[node] = m.core

    @property
    def now(self) -> float:
        """Simulated time, s."""
        return self.world.time

    # -- delivery -------------------------------------------------------------------------------
    def _send(self, writer_name: str, record: str, raw: bytes) -> None:
        """Deliver 16 bytes to every reader of `record` (with the link's faults)."""
        link = self.links.get(record)
        if link is not None:
            if link.drop and self.rng.random() < link.drop:
                return
            if link.delay > 0:
                self._delayed.append((self.now + link.delay, record, raw, writer_name))
                return
        self._deliver(record, raw)

    def _deliver(self, record: str, raw: bytes) -> None:
        world = self.world
        now = world.sample * world.dt  # world.time
        for tap in self.taps:
            tap(record, raw, now)
        route = self._routes.get(record)
        if route is None:
            route = self._route(record)
        world_reader, readers, decode = route
        if now != self._ns_of:
            self._ns_of, self._now_ns = now, round(now * 1e9)
        now_ns = self._now_ns
        # The readers judge the bytes alike: decoded once, each takes (and keeps) a copy. None:
        # each reader's own general path judges, counts and names it.
        fields = None if decode is None else decode(raw)
        given = False
        if world_reader is not None:
            if fields is None:
                taken = world_reader.accept(raw, now_ns)
            else:
                taken, given = world_reader.take(raw, fields, now_ns), True
            if taken is not None:
                world.on_record(record, taken, now)
        out = None  # what the readers answer: a list made only once one does (most do not)
        for m, reader in readers:
            if fields is None:
                taken = reader.accept(raw, now_ns)
            else:
                if given:
                    fields = dict(fields)
                taken, given = reader.take(raw, fields, now_ns), True
            if taken is not None:
                if reader.restarted and (o := m.core.on_writer_restart(record, now)):
                    out = _answer(out, m, o)
                if o := m.core.on_record(record, taken, now):
                    out = _answer(out, m, o)
            elif hasattr(m.core, 'on_reject') and \
                    (o := m.core.on_reject(record, reader.last_reason, now)):
                out = _answer(out, m, o)
        if out:
            self._publish_all(out)

    def _route(self, record: str) -> tuple[RecordReader | None,
                                           list[tuple[_Member, RecordReader]], Callable | None]:
        """Return (the world's reader, [(member, reader)], decode) of `record`.

        `decode`: the readers' fast decoding when every one judges bytes alike (the same schema
        and integrity), else None.
        """
        world_reader = self.world_readers.get(record)
        readers = [(m, m.readers[record]) for m in self.members if record in m.readers]
        every = [r for r in (world_reader, *(r for _m, r in readers)) if r is not None]
        alike = every and all(r.schema is every[0].schema and r.integrity == every[0].integrity
                              for r in every)
        self._routes[record] = route = (world_reader, readers,
                                        every[0].fast_decode if alike else None)
        return route

    def _publish(self, m: _Member, outputs: dict | None) -> None:
        if outputs:
            self._publish_all(((m, outputs),))

    def _publish_all(self, queue: Sequence[tuple[_Member, dict]]) -> None:
        """Send each member's outputs in turn (each record delivered at once, depth first)."""
        self._depth += 1
        if self._depth > MAX_CHAIN:
            self._depth -= 1
            raise RuntimeError('harness: records keep triggering records (a loop?)')
        links = self.links
        try:
            for m, outputs in queue:
                for record, fields in outputs.items():
                    writer = m.writers.get(record)
                    if writer is None:
                        raise KeyError(f'{m.core.node} is not the writer of {record} '
                                       '(msg_schemas)')
                    if record in links:
                        self._send(m.core.node, record, writer.pack(fields))
                    else:
                        self._deliver(record, writer.pack(fields))
        finally:
            self._depth -= 1

    def set_radio_stop(self, on: bool) -> None:
        """Set the hw/radio_stop input: to the world and every core that reads it."""
        self.world.set_radio_stop(on)
        for m in self.members:
            if hasattr(m.core, 'on_radio_stop'):
                m.core.on_radio_stop(on, self.now)

    def inject(self, record: str, raw: bytes) -> None:
        """Put foreign bytes on a record topic (fault injection, fuzzing)."""
        self._deliver(record, bytes(raw))

    # -- stepping ---------------------------------------------------------------------------
    def step(self) -> dict[str, Any]:
        """One world sample, then every node timer that has come due."""
        out = self.world.step()
        now = self.world.time
        if self.world.bumper != self._bumper:  # hw/bumper in the graph (the world's output)
            self._bumper = self.world.bumper
            for m in self.members:
                if hasattr(m.core, 'on_bumper'):
                    m.core.on_bumper(self._bumper, now)
        if self._delayed:
            due = [d for d in self._delayed if d[0] <= now]
            self._delayed = [d for d in self._delayed if d[0] > now]
            for _t, record, raw, _w in due:
                self._deliver(record, raw)
        for record, fields in out['records'].items():
            raw = self.world_writers[record].pack(fields)
            if record in self.links:
                self._send('world', record, raw)
            else:  # no link faults: straight to the readers
                self._deliver(record, raw)
        if out['events']:
            self.events.extend(out['events'])
        if out['frames']:
            self.frames = out['frames']
            # hw/camera/front and hw/camera/rear (sensor_msgs/Image in the graph), front first
            for camera in ('front', 'rear'):
                if (frame := out['frames'].get(camera)) is not None:
                    for m in self.members:
                        if hasattr(m.core, 'on_frame'):
                            self._publish(m, m.core.on_frame(frame, now, camera=camera))
        if out.get('sonar') is not None:  # hw/sonar (sensor_msgs/Range in the graph)
            for m in self.members:
                if hasattr(m.core, 'on_sonar'):
                    self._publish(m, m.core.on_sonar(out['sonar'], now))
        if now + 1e-12 >= self._timers_due:
            self._timers_due = fire_timers(self.members, self._publish, now)
        return out

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step for `seconds` of simulated time, or until `until()` is true (returns it)."""
        return run_for(self, seconds, until)

    def reader(self, node: str, record: str) -> RecordReader:
        """Return a core's reader of `record` (for diagnostics and tests)."""
        for m in self.members:
            if m.core.node == node:
                return m.readers[record]
        raise KeyError(node)


# -- the whole truck ---------------------------------------------------------------------------
DEMO_PROGRAMME = (  # thesis 7.2 tasks 1-7 and fig 3.1 on demo_1983, in an order that needs
    # few laps: each task at a location must reach its marker from upstream, so the tasks at L2
    # are spread over laps, and task 7 and the transfer ride along laps the others make anyway.
    'load at 0 then continue',  # task 1: stop at location n, take on a load, carry on
    'unload at 2 then continue',  # task 2: stop, discharge the load, carry on
    'srm at 1 angle 15',  # task 7: leave the wire at n by an SRM
    'wait at 0 for 3 then continue',  # task 3: stop and dwell, carry on
    'stop at 2 first',  # task 4: the first stop marker
    'load A at 1 and take to 3',  # fig 3.1: load A at B and take to C
    'stop at 2 second',  # task 5: the second stop marker
    'stop at 2 first then second',  # task 6: first, then advance to the second
)
# The CONCIC-II's programme on signs_1991 (Rajagopalan 1991, App. F.6-F.7; the layout's header
# walks it): every road sign met, scripted left and right turns at crosses, T-junctions and
# corners, a wait over a crossing, the R = 2.95 m curve, and a reverse leg led by the rear camera;
# the curve is driven by the feed-forward law on the track it identifies (Rajagopalan 1991, 5.4).
CONCIC2_PROGRAMME = (
    'tape junctions 1 right then reverse for 5 m',  # R2 right, the bay's P21, back out
    # R2 left, P22, the curve, the P21 of north_c's T
    'tape with feed_forward junctions 1 left for 21 m',
    'tape junctions 1 left, 2 right, 3 left, 4 left for 20 m',  # R2, P12, P11, R1: the chord
    'tape junctions 1 straight wait 2, 2 right, 3 right, 4 left',  # R2, P22, P12, R1: the bay
)
CONCIC2_QUICK = CONCIC2_PROGRAMME[:1]  # a scripted turn and a reverse leg, ~43 s simulated


class CameraLegScript:
    """Stand-in executive for route following alone in lock step: one route_command.

    Camera mode, forwards, straight on at junctions, leg 1, unless `command` says otherwise
    (its fields; change them between the phases of a run). `states`: the states route_status
    went through, each once in a row.
    """

    node, period = 'executive', 0.05

    def __init__(self, **command: Any) -> None:
        self.command = {'mode': 'camera', 'srm_angle': 0, 'junction': 'straight',
                        'manoeuvre': 0, 'direction': 'forward', 'junction_number': 0,
                        'junction_wait': 0, 'leg': 1, **command}
        self.states: list[str] = []

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> None:
        """Note route_status's state when it changes."""
        if record == 'route_status' and (not self.states or self.states[-1] != fields['state']):
            self.states.append(fields['state'])

    def tick(self, now: float) -> dict[str, dict[str, Any]]:
        """Send the route_command."""
        return {'route_command': dict(self.command)}


def truck(layout_name: str = 'demo_1983', *, seed: int = 1,
          overrides: Mapping[str, Mapping[str, Any]] | None = None,
          params_file: Path | str | None = None, integrity: str = 'e2e',
          start: tuple[str, float] | None = None,
          station_loads: dict[str, int] | None = None,
          world_params: Any = None) -> Harness:
    """Build the world and the truck's node cores in lock step, set as a launched graph's are.

    The layout's vehicle picks the cores, as it picks the launched graph's nodes: all seven for
    the 1983 Electruk, route following, executive and communications for the CONCIC-II.

    Settings: the graph's parameter file (config/agv_demo.yaml), the layout's
    (`layout_parameters`), then `overrides` ({node: {name: value}}, as agv-launch's `-p
    NODE:NAME:=VALUE`). `seed` seeds world and harness. Like the world node it refuses a layout
    with a marker the sensor cannot read on the route (unless the world's `layout_check` is
    'warn'). `start` and `station_loads` place one truck of a fleet (WorldCore).

    `world_params` (deprecated, warns; goes in the next release): the world's settings whole, a
    WorldParams as the harness took them before `overrides`; the same as
    `overrides={'world': settings.values_of(world_params)}`.
    """
    from agv_nodes.communications.core import CommunicationsCore
    from agv_nodes.executive.core import ExecutiveCore
    from agv_nodes.graph.model import load_graph
    from agv_nodes.load_handling.core import LoadHandlingCore
    from agv_nodes.navigation.core import NavigationCore
    from agv_nodes.package_share import config_dir
    from agv_nodes.position_sensor.core import PositionSensorCore
    from agv_nodes.route_following.core import RouteCore
    from agv_nodes.settings import parameters, settings_from_file, values_of
    from agv_nodes.traction.core import TractionCore
    from agv_nodes.world.layout import layout_parameters, layout_path, load_layout
    from agv_nodes.world.settings import WorldNodeSettings, WorldParams

    params_file = Path(params_file) if params_file else config_dir() / 'agv_demo.yaml'
    lay = load_layout(layout_path(layout_name))
    from_layout = layout_parameters(lay)
    given = {node: dict(values) for node, values in (overrides or {}).items()}
    if world_params is not None:
        warnings.warn("truck(world_params=...) is deprecated and goes in the next release: use "
                      "overrides={'world': {name: value}} (agv_nodes.settings.values_of gives "
                      "a WorldParams' values)", DeprecationWarning, stacklevel=2)
        given['world'] = {**values_of(world_params), **given.get('world', {})}

    def settings(node: str, cls: type, also: type | None = None, **fixed: Any) -> Any:
        values = {**from_layout.get(node, {}), **fixed, **given.get(node, {})}
        known = frozenset(p.name for p in parameters(also)) if also else frozenset()
        if unknown := set(values) - {p.name for p in parameters(cls)} - known:
            raise ValueError(f'truck: node {node}: unknown parameter {sorted(unknown)[0]!r}')
        ours = {name: value for name, value in values.items() if name not in known}
        return settings_from_file(cls, params_file, node, ours, also_known=known)

    world_params = settings('world', WorldParams, WorldNodeSettings, seed=seed)
    if settings('world', WorldNodeSettings, WorldParams).layout_check != 'warn':
        _check(lay, world_params)
    world = WorldCore(lay, world_params, start=start, station_loads=station_loads)
    on_truck = {n.name for n in load_graph().for_truck(lay.vehicle).nodes}  # config/graph.yaml
    cores = [core_type(settings(core_type.node, core_type.settings_type))
             for core_type in (TractionCore, PositionSensorCore, NavigationCore, RouteCore,
                               ExecutiveCore, CommunicationsCore, LoadHandlingCore)
             if core_type.node in on_truck]
    h = Harness(world, cores, integrity=integrity, seed=seed)
    h.cores = {c.node: c for c in cores}
    return h


def _check(layout: Any, world_params: Any) -> None:
    """Refuse a layout with an unreadable marker (the drives, once per layout: result_cache)."""
    from agv_nodes.world.layout import LayoutError
    from agv_nodes.world.layout_check import check_errors

    if errors := check_errors(layout, world_params):
        raise LayoutError('\n'.join(errors))


def submit(h: Harness, text: str) -> None:
    """Hand a task to communications (what a comms/task message does in the graph)."""
    comms: CommunicationsCore = h.cores['communications']
    for m in h.members:
        if m.core is comms:
            h._publish(m, comms.on_task(text, h.now))
