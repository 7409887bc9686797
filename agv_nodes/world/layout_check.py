"""Layout check: whether the truck can read every marker as it drives the route.

On a bend the front axle (the sensor point, Baker 1983, 6.3.2) follows the wire while the rear axle
cuts inside, so the lens (Baker 1983, 5.1) swings off the cards' normal for a few wheelbases, and
likewise after an SRM's landing (7.2). So the check drives the world's Electruk model
(agv_nodes.world.vehicles) with the route-following core's wire law, fed as in the lock-step
harness, every wire from its start and the truck by the route map twice round, and takes each
marker's pass furthest from the thesis's working range (`READ_STANDOFF`, `READ_ANGLE`,
agv_nodes.world.marker_sensor). Whether that pass reads is decided by the world's own sensor
model and the position sensor's decoder, on the pass's lens poses (agv_nodes.world.readability):
a card is refused only when the simulated truck cannot read it, and one near that edge is
marginal. On the belt rig the lens runs along the belt line itself; tape layouts (camera) have no
marker check: their table lists each road sign and where its branches lead
(agv_nodes.world.tape_layout), warns of bends tighter than the camera truck can follow and
says what each crossing met by a reverse leg reads (agv_nodes.world.tape_check). See
docs/architecture.md, "Layout check".
"""

import math
import random

from agv_nodes.result_cache import cached
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import _Every
from agv_nodes.world.guide_wire import GuideWirePickup
from agv_nodes.world.layout import Layout, LayoutError, Marker
from agv_nodes.world.layout_report import Passage, Report
from agv_nodes.world.marker_sensor import axis_on_card, lens_position
from agv_nodes.world.readability import Pose, expected_identity, readability
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.tape_check import reverse_crossings, tight_bends
from agv_nodes.world.tape_layout import branch_ends
from agv_nodes.world.vehicles import Electruk

# Speeds of the executive's demands (executive parameters: cruise_demand 55 % ~ 0.7 m/s, the
# practical top speed of Baker 1983, 7.2; srm_demand 27 % ~ 0.3 m/s, kept to the next landmark).
CRUISE, SRM_SPEED = 0.7, 0.3
VIEW = 0.6  # m: the optics look no further for a card (MarkerSensorModel.optics)
LAPS = 2  # the route map is driven twice round, so what a lap leaves off-wire comes round again


def check_layout(layout: Layout, world: WorldParams | None = None,
                 route: RouteParams | None = None) -> Report:
    """Drive the layout's routes and report each marker's worst pass (see the module docstring)."""
    world = world or WorldParams()
    passages = [Passage(m) for m in layout.markers]
    if layout.kind == 'tape':
        return Report(layout, passages, 'markers not checked: a camera-guided floor'
                      if layout.markers else '', branch_ends(layout.signs, layout.paths),
                      tight_bends(layout, route), reverse_crossings(layout))
    if not layout.markers:
        return Report(layout, passages)
    if layout.kind == 'rig':
        path = layout.paths[layout.start_path]
        _Drive(layout, passages, 'the belt').rig(path, 1.0 / world.sample_rate)
    elif layout.kind == 'tape' or layout.vehicle != 'electruk':
        return Report(layout, passages, 'not checked: markers on a camera-guided floor')
    else:
        route = route or RouteParams()
        for pid, path in layout.paths.items():
            _Drive(layout, passages, f'wire {pid} from its start').truck(
                world, route, (pid, 0.0, 0.0, 0.0),
                path.length * (LAPS if path.closed else 1) + VIEW, route_map=False)
        total = sum(p.length for p in layout.paths.values())
        _Drive(layout, passages, 'from the start by the route map').truck(
            world, route, (layout.start_path, layout.start_at, layout.start_lateral,
                           layout.start_heading), total * LAPS, route_map=True)
    for p in passages:
        if p.passed and p.poses and expected_identity(p.marker) is not None:
            p.read = readability(p.marker, p.poses, world, p.angle, p.standoff)
    return Report(layout, passages)


def check_findings(layout: Layout, world: WorldParams | None = None) -> dict[str, list[str]]:
    """Return `check_layout`'s lines, {'errors': [...], 'warnings': [...]}, computed once.

    The drives and replays take seconds and every world start (and lock-step truck) asks, so
    the lines are kept in agv_nodes.result_cache by what they depend on: the layout file, the
    markers it kept (a world's `remove_markers`) and the vehicle and sensor settings.
    """
    world = world or WorldParams()

    def compute() -> dict[str, list[str]]:
        report = check_layout(layout, world)
        return {'errors': report.errors(), 'warnings': report.warnings()}

    return cached('layout_check', _drive_inputs(layout, world) + repr(world.sensor), compute)


def check_errors(layout: Layout, world: WorldParams | None = None) -> list[str]:
    """Return `check_layout(...).errors()`, computed once per layout, settings and code."""
    return check_findings(layout, world)['errors']


JUNCTION_DRIVE = 40.0  # m driven from each junction: past its landing and the way it opens


def _drive_inputs(layout: Layout, world: WorldParams) -> str:
    """Return what a drive's result depends on besides the code: the cache's key."""
    return repr((str(layout.file), layout.file.read_text(), layout.markers, world.electruk,
                 world.pickup, world.sample_rate, world.substeps, world.guide_wire_rate,
                 world.odometry_rate))


def route_passes(layout: Layout, world: WorldParams | None = None) -> list[tuple[str, float]]:
    """Return the cards a truck passes driving the route map from the start, twice round.

    Each as (marker name, m the sensor point had driven when the card's centre crossed the lens's
    axis), in order: how the track graph (agv_nodes.fleet.track_graph) learns where each SRM
    lands. Kept in agv_nodes.result_cache as check_errors is; [] for a layout without an
    Electruk route.
    """
    world = world or WorldParams()
    if layout.kind != 'wire' or layout.vehicle != 'electruk' or not layout.markers:
        return []

    def drive() -> list[tuple[str, float]]:
        passages = [Passage(m) for m in layout.markers]
        run = _Drive(layout, passages, 'from the start by the route map')
        total = sum(p.length for p in layout.paths.values())
        run.truck(world, RouteParams(), (layout.start_path, layout.start_at,
                                         layout.start_lateral, layout.start_heading),
                  total * LAPS, route_map=True)
        return run.log

    inputs = _drive_inputs(layout, world)
    return [tuple(p) for p in cached('route_passes', inputs, drive)]


def junction_passes(layout: Layout, world: WorldParams | None = None
                    ) -> dict[str, list[tuple[str, float]]]:
    """Return, per junction of the layout, the cards a truck passes leaving the wire there.

    Each drive starts 3 m before the junction's location marker and takes its SRM (the task's
    choice, `srm at N angle A`) and no other junction's, the route map elsewhere, for
    `JUNCTION_DRIVE` m or until the wire ends: how the track graph learns where a junction's
    SRM lands and what lies on the way it opens. Passes as route_passes gives them, cached
    the same way.
    """
    world = world or WorldParams()
    if layout.kind != 'wire' or layout.vehicle != 'electruk' or not layout.junctions:
        return {}
    by_name = {m.name: m for m in layout.markers}

    def drive() -> dict[str, list[tuple[str, float]]]:
        out = {}
        for entry in layout.junctions:
            name, _, angle = entry.partition(':')
            m = by_name[name]
            run = _Drive(layout, [Passage(p) for p in layout.markers], f'leaving {name}')
            run.truck(world, RouteParams(), (m.path, max(m.at - 3.0, 0.0), 0.0, 0.0),
                      JUNCTION_DRIVE, route_map=True, junctions={name: int(angle)})
            out[name] = run.log
        return out

    inputs = _drive_inputs(layout, world)
    return {k: [tuple(p) for p in v] for k, v in cached('junction_passes', inputs,
                                                        drive).items()}


def enforce(layout: Layout, world: WorldParams | None = None, mode: str = 'error') -> list[str]:
    """Check as the world does: LayoutError of the unreadable markers' lines (mode 'error').

    Returns the lines to log: the marginal markers', and with mode 'warn' the unreadable too.
    """
    found = check_findings(layout, world)
    if found['errors'] and mode != 'warn':
        raise LayoutError('\n'.join(found['errors']))
    return found['errors'] + found['warnings']


class _Drive:
    """One drive: the lens's passes over the cards, kept where they are the worst so far."""

    def __init__(self, layout: Layout, passages: list[Passage], label: str) -> None:
        self.layout, self.passages, self.label = layout, passages, label
        self._side: dict[int, tuple[float, float, float]] = {}  # marker -> last (t, u, angle)
        self._trace: dict[int, list[Pose]] = {}  # marker -> lens poses while it is in view
        self._worst: set[int] = set()  # markers whose pass in view is their worst so far
        self.passed: list[Marker] = []  # cards whose centre the axis crossed on the last sample
        self.log: list[tuple[str, float]] = []  # every card counted, with the distance driven
        self.distance = 0.0  # m the sensor point has driven: on a wire, the wire's length

    def look(self, lens: tuple[float, float], heading: float, count: bool = True) -> None:
        """Note the cards whose centre the axis just crossed (not `count`: leaving their wire)."""
        self.passed = []
        for i, p in enumerate(self.passages):
            m = p.marker
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            distance = math.hypot(dx, dy)
            if count:
                p.closest = min(p.closest, distance)
            if distance <= VIEW:
                self._trace.setdefault(i, []).append((lens, heading))
            elif i in self._trace:
                self._leave(i)
            on_card = axis_on_card(lens, heading, m) if distance <= VIEW else None
            if on_card is None:
                self._side.pop(i, None)
                continue
            t, u, _cos = on_card
            # The card's normal (facing the lens) against the axis reversed, + = card turned left.
            angle = math.degrees(math.atan2(-m.normal[0] * math.cos(heading)
                                            - m.normal[1] * math.sin(heading),
                                            m.normal[1] * math.cos(heading)
                                            - m.normal[0] * math.sin(heading)))
            before = self._side.get(i)
            self._side[i] = (t, u, angle)
            if before is None or (before[1] < 0.0) == (u < 0.0) or not count:
                continue
            f = before[1] / (before[1] - u)  # where between the samples u was 0
            crossing = Passage(m, before[0] + f * (t - before[0]),
                               before[2] + f * (angle - before[2]), self.label)
            if crossing.score > p.score or not p.passed:
                p.standoff, p.angle, p.drive = crossing.standoff, crossing.angle, self.label
                self._worst.add(i)
            self.passed.append(m)
            self.log.append((m.name, self.distance))

    def _leave(self, i: int) -> None:
        """Close a card's pass as it leaves the view: keep its poses if it was its worst."""
        poses = self._trace.pop(i)
        if i in self._worst:
            self._worst.discard(i)
            self.passages[i].poses = poses

    def finish(self) -> None:
        """End the drive: the cards still in view leave it."""
        for i in list(self._trace):
            self._leave(i)

    def rig(self, path, dt: float) -> None:
        """Run the lens along the belt line, as the belt rig does (WorldCore._step_rig)."""
        s = 0.0
        while s <= path.length:
            x, y, h = path.pose_at(s)
            self.look((x, y), h)
            s += float(self.layout.rig.get('speed', 1.0)) * dt
        self.finish()

    def truck(self, world: WorldParams, route_params: RouteParams,
              start: tuple[str, float, float, float], distance: float, route_map: bool,
              junctions: dict[str, int] | None = None) -> None:
        """Drive the Electruk `distance` m from `start` (path, at, lateral, heading).

        Speed held (cruise; SRM speed from an SRM to the next landmark), steered by the
        route-following core from the pickup's coils, as the harness wires them. `junctions`:
        location markers (by name) where the truck also leaves its wire, at the angle given,
        as a task `srm at N` has it do at a junction.
        """
        junctions = junctions or {}
        lay = self.layout
        truck = Electruk(world.electruk)
        pid, at, lateral, heading = start
        x, y, h = lay.paths[pid].pose_at(at)
        h += heading
        x, y = x - math.sin(h) * lateral, y + math.cos(h) * lateral
        wheelbase = world.electruk.wheelbase
        st = truck.state
        st.x, st.y, st.heading = x - wheelbase * math.cos(h), y - wheelbase * math.sin(h), h
        wires = [w for w in lay.paths.values() if w.width == 0.0]
        # Its own seed: the check of a layout is the same whatever seed the world runs with.
        pickup = GuideWirePickup(world.pickup, wires, random.Random(0))
        core = RouteCore(route_params)
        core.on_record('route_command', {'mode': 'follow_wire', 'srm_angle': 0,
                                         'junction': 'straight', 'manoeuvre': 0}, 0.0)
        srm_map = {int(loc): int(angle) for loc, angle in
                   (entry.split(':') for entry in lay.srm_map)} if route_map else {}
        dt = 1.0 / world.sample_rate
        wire_every = _Every(world.guide_wire_rate, world.sample_rate)
        odo_every = _Every(world.odometry_rate, world.sample_rate)
        next_tick, manoeuvre, speed, odo, sample = 0.0, 0, CRUISE, [0.0, 0.0], 0
        if (period := core.period) is None:  # route following always has its timer
            raise ValueError('layout check: a route-following core without a period')
        last_point = truck.sensor_point
        while st.distance < distance:
            sample += 1
            now = sample * dt
            for _ in range(world.substeps):
                st.speed = speed
                truck.step(dt / world.substeps)
            st.speed = speed
            point = truck.sensor_point
            self.distance += math.hypot(point[0] - last_point[0], point[1] - last_point[1])
            last_point = point
            # Cards passed while an SRM leaves the wire (before it finds the next) stand where
            # the truck is not going: a stop marker after the SRM's location is for a truck
            # that stays on the wire, and the drive of that wire from its start passes it.
            self.look(lens_position(truck.sensor_point, st.heading, lay.sensor_lateral),
                      st.heading, count=core.state != 'srm_running')
            for m in self.passed:
                if m.kind != 'location':
                    continue
                speed = CRUISE
                angle = junctions.get(m.name, srm_map.get(m.identity))
                if angle is not None:
                    manoeuvre += 1
                    speed = SRM_SPEED
                    core.on_record('route_command', {'mode': 'srm', 'junction': 'straight',
                                                     'srm_angle': angle,
                                                     'manoeuvre': manoeuvre}, now)
            if wire_every.due(sample):
                left, right = pickup.coils(*truck.sensor_point, st.heading)
                core.on_record('guide_wire', {'left_coil': left, 'right_coil': right}, now)
            if odo_every.due(sample):
                rims = truck.wheel_speeds()
                odo = [d + v / world.odometry_rate for d, v in zip(odo, rims, strict=True)]
                core.on_record('wheel_odometry', {
                    'left_speed': round(rims[0] * 1000), 'right_speed': round(rims[1] * 1000),
                    'left_distance': round(odo[0] * 1000) & 0xFFFF,
                    'right_distance': round(odo[1] * 1000) & 0xFFFF}, now)
            while next_tick <= now + 1e-12:
                next_tick += period
                if (out := core.tick(now)) is None:  # its tick always steers
                    raise ValueError('layout check: route following sent no steering command')
                command = out['steering_command']
                truck.steer_demand = command['angle'] / 1000.0
                truck.steer_enable = bool(command['enable'])
            if core.state == 'lost':
                break  # the wire has ended (or an SRM found none): the truck would stop here
        self.finish()
