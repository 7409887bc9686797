"""Layout check: the marker sensor's view of every marker as the truck drives the route.

On a bend the front axle (the sensor point, Baker 1983, 6.3.2) follows the wire while the rear axle
cuts inside, so the lens (Baker 1983, 5.1) swings off the cards' normal for a few wheelbases, and
likewise after an SRM's landing (7.2). So the check drives the world's Electruk model
(agv_nodes.world.vehicles) with the route-following core's wire law, fed as in the lock-step
harness, every wire from its start and the truck by the route map twice round, and takes each
marker's pass furthest from the sensor's working range (`READ_STANDOFF`, `READ_ANGLE`,
agv_nodes.world.marker_sensor). On the belt rig the lens runs along the belt line itself; tape
layouts (camera) have no marker check: their table lists each road sign and where its branches
lead (agv_nodes.world.tape_layout). See docs/architecture.md, "Layout check".
"""

from dataclasses import dataclass, field
import math
import random

from agv_nodes.result_cache import cached
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import _Every
from agv_nodes.world.guide_wire import GuideWirePickup
from agv_nodes.world.layout import Layout, LayoutError, Marker
from agv_nodes.world.marker_sensor import READ_ANGLE, READ_STANDOFF, axis_on_card, lens_position
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.tape_layout import branch_ends
from agv_nodes.world.vehicles import Electruk

# Speeds of the executive's demands (executive parameters: cruise_demand 55 % ~ 0.7 m/s, the
# practical top speed of Baker 1983, 7.2; srm_demand 27 % ~ 0.3 m/s, kept to the next landmark).
CRUISE, SRM_SPEED = 0.7, 0.3
VIEW = 0.6  # m: the optics look no further for a card (MarkerSensorModel.optics)
LAPS = 2  # the route map is driven twice round, so what a lap leaves off-wire comes round again


@dataclass
class Passage:
    """A marker as the truck passes it: the pass of all drives furthest from the working range."""

    marker: Marker
    standoff: float = math.nan  # m, lens to card along the optical axis, as it meets the centre
    angle: float = math.nan  # degrees, the card's normal off the axis (+ = card turned left)
    drive: str = ''
    closest: float = math.inf  # m, the lens's closest approach to the card centre (any drive)

    @property
    def passed(self) -> bool:
        """Return True when the optical axis crossed the card centre on some drive."""
        return not math.isnan(self.standoff)

    @property
    def score(self) -> float:
        """Return how far out it is as a fraction of the range's half-width (> 1: outside)."""
        if not self.passed:
            return math.inf
        lo, hi = READ_STANDOFF
        return max(abs(self.standoff - (lo + hi) / 2.0) / ((hi - lo) / 2.0),
                   abs(self.angle) / READ_ANGLE)

    @property
    def in_range(self) -> bool:
        """Return True when the sensor can read the marker on every drive."""
        lo, hi = READ_STANDOFF
        return self.passed and lo <= self.standoff <= hi and abs(self.angle) <= READ_ANGLE

    def problem(self) -> str:
        """Return what is out of range, and by how much ('' when it is in range)."""
        if not self.passed:
            return (f'never crossed by the optical axis as driven (closest {self.closest:.3f} m; '
                    'seen edge-on, off the route or beyond the view)')
        lo, hi = READ_STANDOFF
        out = []
        if not lo <= self.standoff <= hi:
            far = self.standoff > hi
            by = self.standoff - hi if far else lo - self.standoff
            out.append(f'standoff {self.standoff:.3f} m as driven, sensor reads {lo:.3f}-'
                       f'{hi:.3f} m: {by:.3f} m too {"far" if far else "near"}')
        if abs(self.angle) > READ_ANGLE:
            out.append(f'angle {self.angle:+.1f} deg as driven, sensor reads within '
                       f'+-{READ_ANGLE:.1f} deg: {abs(self.angle) - READ_ANGLE:.1f} deg too '
                       'oblique')
        return '; '.join(out)


@dataclass
class Report:
    """Every marker of a layout as driven."""

    layout: Layout
    passages: list[Passage]
    note: str = ''
    signs: list[str] = field(default_factory=list)  # tape floors: each sign and its branches

    def errors(self) -> list[str]:
        """Return one line per marker the sensor cannot read."""
        return [f'layout {self.layout.file}: marker {p.marker.name!r} at '
                f'({p.marker.centre[0]:.2f}, {p.marker.centre[1]:.2f}): {p.problem()}'
                f'{f" ({p.drive})" if p.drive else ""}'
                for p in self.passages if not p.in_range]

    def table(self) -> str:
        """Return the per-marker table: marker, standoff m, angle deg, in range, where."""
        lay = self.layout
        lines = [f'layout {lay.file} ({lay.kind}, {lay.vehicle}): {len(self.passages)} markers'
                 f'{f"; {self.note}" if self.note else ""}']
        if self.passages:
            lines.append(f'{"marker":8} {"path":>5} {"at m":>7} {"standoff m":>10} '
                         f'{"angle deg":>9} {"in range":>8}  worst pass')
        for p in self.passages:
            m = p.marker
            standoff = f'{p.standoff:.3f}' if p.passed else '-'
            angle = f'{p.angle:+.1f}' if p.passed else '-'
            lines.append(f'{m.name:8} {m.path:>5} {m.at:7.3f} {standoff:>10} {angle:>9} '
                         f'{"yes" if p.in_range else "no":>8}  {p.drive}')
        if self.signs:
            lines.append(f'{len(self.signs)} road signs (Rajagopalan 1991, 4.3):')
            lines += [f'  {line}' for line in self.signs]
        return '\n'.join(lines)


def check_layout(layout: Layout, world: WorldParams | None = None,
                 route: RouteParams | None = None) -> Report:
    """Drive the layout's routes and report each marker's worst pass (see the module docstring)."""
    world = world or WorldParams()
    passages = [Passage(m) for m in layout.markers]
    if layout.kind == 'tape':
        return Report(layout, passages, 'markers not checked: a camera-guided floor'
                      if layout.markers else '', branch_ends(layout.signs, layout.paths))
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
    return Report(layout, passages)


def check_errors(layout: Layout, world: WorldParams | None = None) -> list[str]:
    """Return `check_layout(...).errors()`, computed once per layout, settings and code.

    The drives take seconds and every world start (and lock-step truck) asks, so the lines are
    kept in agv_nodes.result_cache by what the drives depend on: the layout file, the markers
    it kept (a world's `remove_markers`) and the vehicle settings the drives use.
    """
    world = world or WorldParams()
    inputs = _drive_inputs(layout, world)
    return cached('layout_check', inputs, lambda: check_layout(layout, world).errors())


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
    """Check as the world does: LayoutError of the lines (mode 'error'), else return them."""
    errors = check_errors(layout, world)
    if errors and mode != 'warn':
        raise LayoutError('\n'.join(errors))
    return errors


class _Drive:
    """One drive: the lens's passes over the cards, kept where they are the worst so far."""

    def __init__(self, layout: Layout, passages: list[Passage], label: str) -> None:
        self.layout, self.passages, self.label = layout, passages, label
        self._side: dict[int, tuple[float, float, float]] = {}  # marker -> last (t, u, angle)
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
            self.passed.append(m)
            self.log.append((m.name, self.distance))

    def rig(self, path, dt: float) -> None:
        """Run the lens along the belt line, as the belt rig does (WorldCore._step_rig)."""
        s = 0.0
        while s <= path.length:
            x, y, h = path.pose_at(s)
            self.look((x, y), h)
            s += float(self.layout.rig.get('speed', 1.0)) * dt

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
                next_tick += core.period
                command = core.tick(now)['steering_command']
                truck.steer_demand = command['angle'] / 1000.0
                truck.steer_enable = bool(command['enable'])
            if core.state == 'lost':
                return  # the wire has ended (or an SRM found none): the truck would stop here
