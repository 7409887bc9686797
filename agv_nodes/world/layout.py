"""World layouts (config/layouts/*.yaml): guide wires or tape, markers on stands, workstations.

A path (guide wire or optical tape) is a start pose and straight and arc segments, sampled every
`step` m. Markers are placed by (path, distance along it), the card facing the path from the sensor
side at the standoff (Baker 1983, 4.4 and 5.1: 300 mm from the lens; the route held to +-1 cm, this
reproduction's goal: the thesis states none). Every error names the file, the key and the value.
Paths and the road signs of tape floors are built by agv_nodes.world.tape_layout.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
import re
from typing import Any

from agv_nodes.markers import LOCATION_PATTERNS, STOP_STRIP, WHITE_CARD
from agv_nodes.package_share import config_dir, read_mapping
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameters

# Paths and road signs live in tape_layout; imported here too, where callers have found them.
from agv_nodes.world.tape_layout import SIGN_BRANCHES as SIGN_BRANCHES
from agv_nodes.world.tape_layout import LayoutError as LayoutError
from agv_nodes.world.tape_layout import Path2D as Path2D
from agv_nodes.world.tape_layout import add_sign
from agv_nodes.world.tape_layout import build_path as build_path
from agv_nodes.world.tape_layout import num as _num


@dataclass
class Marker:
    """A marker card on a stand beside a path."""

    kind: str  # 'location' | 'stop' | 'white'
    identity: int  # location 0-3; stop markers: index within their station (0, 1)
    path: str
    at: float  # along-path distance of the card centre, m
    rows: tuple[str, str]
    standoff: float  # lens to card plane, m
    height: float  # card centre above the sensor axis, m (+ = card higher)
    yaw: float  # card rotation about the vertical, rad (0 = square to the sensor)
    station: str = ''
    conveyor: str = ''
    # Placed geometry (world frame): card centre, downstream unit vector, normal toward path.
    # Plain float tuples, not numpy arrays: the optics read them 340 times a second per card
    # in view, and arithmetic on numpy scalars costs several times that on floats.
    centre: tuple[float, float] = (0.0, 0.0)
    along: tuple[float, float] = (1.0, 0.0)
    normal: tuple[float, float] = (0.0, 1.0)
    # A location marker's own name, where its identity is on the floor more than once: the
    # house number of Baker 1983, 8.5 (see _check_locations).
    label: str = ''

    @property
    def name(self) -> str:
        """Short label for reports: L0..L3 (or the layout's name), <station>.<n>, W."""
        if self.kind == 'location':
            return self.label or f'L{self.identity}'
        if self.kind == 'stop':
            return f'{self.station or "S"}.{self.identity + 1}'
        return 'W'

    @property
    def columns(self) -> int:
        """Element columns on the card."""
        return len(self.rows[0])


@dataclass
class Station:
    """A workstation with a fixed conveyor (Baker 1983, 6.3.2, fig 7.14)."""

    id: str
    has_load: bool
    capacity: int


@dataclass
class Layout:
    """Everything on the floor."""

    name: str
    file: Path
    vehicle: str
    paths: dict[str, Path2D]
    markers: list[Marker]
    stations: dict[str, Station]
    start_path: str
    start_at: float
    start_lateral: float
    start_heading: float  # extra heading relative to the path, rad
    sensor_lateral: float  # marker sensor lens distance right of the sensor point, m
    kind: str = 'wire'  # 'wire' | 'tape' | 'rig'
    rig: dict[str, Any] = field(default_factory=dict)
    route_limit: float = 0.0  # m of travel per task before the world reports a limit (0 = none)
    description: str = ''
    signs: list[dict[str, Any]] = field(default_factory=list)  # junction road signs (tape)
    # Where the route leaves a wire by a software-resident manoeuvre: 'location:angle' (deg,
    # + = left). The floor's route map: launches and the lock-step harness hand it to the
    # executive (its srm_map), which on the 1983 truck held it in its programme.
    srm_map: tuple[str, ...] = ()
    # A tape layout's camera law for legs whose task does not choose one (route following's
    # camera_law: feedback or feed_forward); '' leaves route following's own.
    camera_law: str = ''
    # A fleet's places, one per truck in order: truck k is set down at the k-th stop marker
    # (agv-launch --trucks) and the dispatcher parks it there when it has no work.
    parking: tuple[str, ...] = ()
    # Junctions: 'NAME:angle' entries, location markers (by name) where a task may leave the
    # wire by an SRM at that angle (deg, + = left) and so take another way (`srm at N angle
    # A`); unlike the route map's, a truck not told to stays on its wire.
    junctions: tuple[str, ...] = ()
    # Obstacles standing from the start (agv_nodes/world/obstacles.py): the sonar sees them.
    obstacles: list[Any] = field(default_factory=list)


_MARKER_KEYS = {'kind', 'identity', 'path', 'at', 'station', 'conveyor', 'standoff', 'height',
                'yaw', 'name'}
_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]{0,15}')
_TOP_KEYS = {'layout', 'description', 'vehicle', 'kind', 'wires', 'tapes', 'markers',
             'stations', 'start', 'sensor', 'rig', 'route_limit', 'step', 'signs', 'srm_map',
             'camera_law', 'parking', 'junctions', 'obstacles'}


def load_layout(file: Path | str) -> Layout:
    """Load and validate a layout file."""
    file = Path(file)
    doc = read_mapping(file, LayoutError, _TOP_KEYS)
    name = doc.get('layout')
    if name != file.stem:
        raise LayoutError(f'{file}: key layout: {name!r} must equal the file name')
    kind = doc.get('kind', 'wire')
    if kind not in ('wire', 'tape', 'rig'):
        raise LayoutError(f'{file}: key kind: {kind!r} not one of wire, tape, rig')
    vehicle = doc.get('vehicle', 'electruk' if kind != 'tape' else 'concic2')
    if vehicle not in ('electruk', 'concic2'):
        raise LayoutError(f'{file}: key vehicle: {vehicle!r} not one of electruk, concic2')
    camera_law = doc.get('camera_law', '')
    laws = _camera_laws()
    if camera_law and (kind != 'tape' or camera_law not in laws):
        raise LayoutError(f'{file}: key camera_law: {camera_law!r} not one of '
                          f'{", ".join(laws)} (on a tape layout)')
    step = _num(doc.get('step', 0.02), file, 'step', 0.001, 0.5)
    paths: dict[str, Path2D] = {}
    for group in ('wires', 'tapes'):
        for i, spec in enumerate(doc.get(group) or []):
            key = f'{group}[{i}]'
            if not isinstance(spec, dict) or 'id' not in spec:
                raise LayoutError(f'{file}: key {key}: {spec!r} needs an id')
            pid = str(spec['id'])
            if pid in paths:
                raise LayoutError(f'{file}: key {key}.id: {pid!r} used twice')
            width = _num(spec.get('width', 0.03 if group == 'tapes' else 0.0), file,
                         f'{key}.width', 0.0, 0.2)
            current = _num(spec.get('current', 1.0), file, f'{key}.current', 0.0, 10.0)
            paths[pid] = build_path(pid, spec.get('start'), spec.get('segments'), step, file,
                                    key, width, current)
    if not paths:
        raise LayoutError(f'{file}: key wires: a layout needs at least one wire or tape')
    sensor = doc.get('sensor') or {}
    standoff = _num(sensor.get('standoff', 0.300), file, 'sensor.standoff', 0.2, 0.4)
    sensor_lateral = _num(sensor.get('lateral', 0.45), file, 'sensor.lateral', 0.0, 2.0)
    stations: dict[str, Station] = {}
    for i, spec in enumerate(doc.get('stations') or []):
        key = f'stations[{i}]'
        sid = str(spec.get('id', ''))
        if not sid or sid in stations:
            raise LayoutError(f'{file}: key {key}.id: {sid!r} missing or used twice')
        cap = spec.get('capacity', 1)
        if not isinstance(cap, int) or cap < 1:
            raise LayoutError(f'{file}: key {key}.capacity: {cap!r} must be an integer >= 1')
        stations[sid] = Station(sid, bool(spec.get('has_load', False)), cap)
    rig = dict(doc.get('rig') or {})
    card = {'standoff': standoff, 'height': 0.0, 'yaw': 0.0}
    if kind == 'rig':  # the belt rig sets one distance, height and angle for every card
        card.update({k: rig[k] for k in ('standoff', 'height') if k in rig})
        card['yaw'] = rig.get('angle', 0.0)
    markers = [_load_marker(m, i, file, paths, stations, card, sensor_lateral)
               for i, m in enumerate(doc.get('markers') or [])]
    srm_map = _srm_map(doc.get('srm_map') or [], file)
    _check_locations(markers, srm_map, file)
    signs = [add_sign(spec, i, file, paths, step) for i, spec in enumerate(doc.get('signs')
                                                                             or [])]
    start = doc.get('start') or {}
    start_path = str(start.get('path', next(iter(paths))))
    if start_path not in paths:
        raise LayoutError(f'{file}: key start.path: {start_path!r} is no wire or tape')
    start_at = _num(start.get('at', 0.0), file, 'start.at', 0.0, paths[start_path].length)
    layout = Layout(
        name=name, file=file, vehicle=vehicle, paths=paths, markers=markers, stations=stations,
        start_path=start_path, start_at=start_at,
        start_lateral=_num(start.get('lateral', 0.0), file, 'start.lateral', -1.0, 1.0),
        start_heading=math.radians(_num(start.get('heading', 0.0), file, 'start.heading',
                                        -90.0, 90.0)),
        sensor_lateral=sensor_lateral, kind=kind, rig=rig,
        route_limit=_num(doc.get('route_limit', 0.0), file, 'route_limit', 0.0, 1e4),
        description=' '.join(str(doc.get('description', '')).split()), signs=signs,
        srm_map=srm_map, camera_law=camera_law,
        parking=_parking(doc.get('parking') or [], file, markers),
        junctions=_junctions(doc.get('junctions') or [], file, markers, srm_map),
        obstacles=_obstacles(doc.get('obstacles') or [], file))
    if kind == 'rig':
        _check_rig(layout, file)
    return layout


def _obstacles(specs: Any, file: Path) -> list[Any]:
    """Return the layout's obstacles, or LayoutError naming the file, key and value."""
    from agv_nodes.world.obstacles import ObstacleError, obstacle

    if not isinstance(specs, list):
        raise LayoutError(f'{file}: key obstacles: {specs!r} must be a list')
    out = []
    for i, spec in enumerate(specs):
        try:
            out.append(obstacle(spec, f'obstacles[{i}]'))
        except ObstacleError as exc:
            raise LayoutError(f'{file}: {exc}') from None
    if len({o.name for o in out}) != len(out):
        raise LayoutError(f'{file}: key obstacles: a name used twice')
    return out


def _load_marker(spec: Any, i: int, file: Path, paths: dict[str, Path2D],
                 stations: dict[str, Station], card: dict[str, float],
                 sensor_lateral: float) -> Marker:
    key = f'markers[{i}]'
    if not isinstance(spec, dict):
        raise LayoutError(f'{file}: key {key}: {spec!r} must be a mapping')
    for k in spec:
        if k not in _MARKER_KEYS:
            raise LayoutError(f'{file}: key {key}.{k}: unknown (known: '
                              f'{", ".join(sorted(_MARKER_KEYS))})')
    kind = spec.get('kind')
    if kind not in ('location', 'stop', 'white'):
        raise LayoutError(f'{file}: key {key}.kind: {kind!r} not one of location, stop, white')
    pid = str(spec.get('path', next(iter(paths))))
    if pid not in paths:
        raise LayoutError(f'{file}: key {key}.path: {pid!r} is no wire or tape')
    path = paths[pid]
    at = _num(spec.get('at'), file, f'{key}.at', 0.0, path.length)
    identity = spec.get('identity', 0)
    station = str(spec.get('station', ''))
    if kind == 'location':
        if identity not in LOCATION_PATTERNS:
            raise LayoutError(f'{file}: key {key}.identity: {identity!r} not a location 0-3')
        rows = LOCATION_PATTERNS[identity]
    elif kind == 'stop':
        if station and station not in stations:
            raise LayoutError(f'{file}: key {key}.station: {station!r} is no station')
        rows = STOP_STRIP
    else:
        rows = WHITE_CARD
    label = spec.get('name', '')
    if label and (kind != 'location' or not isinstance(label, str) or not _NAME.fullmatch(label)):
        raise LayoutError(f'{file}: key {key}.name: {label!r}: only a location marker is named, '
                          'a letter then up to 15 letters, digits or _')
    conveyor = str(spec.get('conveyor', 'first' if kind == 'stop' else ''))
    if kind == 'stop' and conveyor not in ('first', 'second'):
        raise LayoutError(f'{file}: key {key}.conveyor: {conveyor!r} not first or second')
    m = Marker(kind=kind, identity=int(identity) if kind == 'location' else
               (0 if conveyor == 'first' else 1), path=pid, at=at, rows=rows,
               standoff=_num(spec.get('standoff', card['standoff']), file, f'{key}.standoff',
                             0.2, 0.4),
               height=_num(spec.get('height', card['height']), file, f'{key}.height', -0.05,
                           0.05),
               yaw=math.radians(_num(spec.get('yaw', card['yaw']), file, f'{key}.yaw', -45.0,
                                     45.0)),
               station=station, conveyor=conveyor, label=label)
    x, y, h = (float(v) for v in path.pose_at(at))
    reach = sensor_lateral + m.standoff
    m.centre = (x + math.sin(h) * reach, y - math.cos(h) * reach)
    # The card faces back toward the path, turned by `yaw` about the vertical.
    m.normal = (-math.sin(h + m.yaw), math.cos(h + m.yaw))
    m.along = (math.cos(h + m.yaw), math.sin(h + m.yaw))
    return m


def _check_locations(markers: list[Marker], srm_map: tuple[str, ...], file: Path) -> None:
    """Refuse two location markers of one name, or two of a location the route map leaves at.

    With four identities (Baker 1983, 4.4) a floor of more locations repeats them, each
    marker named like a house number in a street (8.5); the truck still knows only the
    identity, and its central computer tells the markers apart by the way the truck came.
    The route map leaves the wire at every marker of its locations, so those stay unique.
    """
    seen: dict[str, int] = {}
    for i, m in enumerate(markers):
        if m.kind != 'location':
            continue
        if m.name in seen:
            raise LayoutError(f'{file}: key markers[{i}].name: {m.name!r} is markers'
                              f'[{seen[m.name]}] too: a location marker whose identity is on the '
                              'floor more than once needs a name of its own')
        seen[m.name] = i
    for entry in srm_map:
        location = int(entry.split(':')[0])
        at = [i for i, m in enumerate(markers) if m.kind == 'location' and m.identity == location]
        if len(at) > 1:
            raise LayoutError(f'{file}: key srm_map: {entry!r}: location {location} is markers '
                              f'{at}: the route map leaves the wire at every marker of its '
                              'locations, so each of them has one marker')


def _parking(entries: Any, file: Path, markers: list[Marker]) -> tuple[str, ...]:
    stops = [m.name for m in markers if m.kind == 'stop']
    if not isinstance(entries, list):
        raise LayoutError(f'{file}: key parking: {entries!r} must be a list of stop markers')
    for entry in entries:
        if entry not in stops or entries.count(entry) > 1:
            raise LayoutError(f'{file}: key parking: {entry!r} is not a stop marker of the '
                              f'layout ({", ".join(stops)}), or is named twice')
    return tuple(entries)


def _junctions(entries: Any, file: Path, markers: list[Marker], srm_map: tuple[str, ...]
               ) -> tuple[str, ...]:
    """Return the layout's junctions: 'NAME:angle', a location marker off the route map."""
    locations = {m.name: m for m in markers if m.kind == 'location'}
    mapped = {int(e.split(':')[0]) for e in srm_map}
    if not isinstance(entries, list):
        raise LayoutError(f"{file}: key junctions: {entries!r} must be a list of 'NAME:angle'")
    for entry in entries:
        name, _, angle = str(entry).partition(':')
        try:
            ok = -45 <= int(angle) <= 45 and int(angle) != 0
        except ValueError:
            ok = False
        if not ok or name not in locations or locations[name].identity in mapped:
            raise LayoutError(f"{file}: key junctions: {entry!r} is not 'NAME:angle' (a "
                              'location marker off the route map, angle -45..45 degrees, '
                              'not 0)')
    return tuple(str(e) for e in entries)


def _srm_map(entries: Any, file: Path) -> tuple[str, ...]:
    """Return the layout's route map: 'location:angle' entries, location 0-31, angle -45..45."""
    if not isinstance(entries, list):
        raise LayoutError(f'{file}: key srm_map: {entries!r} must be a list of '
                          "'location:angle'")
    for entry in entries:
        location, _, angle = str(entry).partition(':')
        try:
            ok = 0 <= int(location) <= 31 and -45 <= int(angle) <= 45
        except ValueError:
            ok = False
        if not ok:
            raise LayoutError(f"{file}: key srm_map: {entry!r} is not 'location:angle' "
                              '(location 0-31, angle -45..45 degrees)')
    return tuple(str(e) for e in entries)


def _check_rig(layout: Layout, file: Path) -> None:
    rig = layout.rig
    for key, lo, hi in (('speed', 0.01, 5.0), ('standoff', 0.2, 0.4), ('height', -0.05, 0.05),
                        ('angle', -45.0, 45.0)):
        if key in rig:
            _num(rig[key], file, f'rig.{key}', lo, hi)


def _camera_laws() -> tuple[str, ...]:
    """Return the laws route following's camera_law parameter takes (the key sets it)."""
    return next(p.spec.choices for p in parameters(RouteParams) if p.name == 'camera_law')


def layout_parameters(layout: Layout) -> dict[str, dict[str, Any]]:
    """Return what a layout sets in its truck's nodes: vehicle, guidance, route map, cameras, law.

    A tape layout is driven by the CONCIC-II's cameras (both rendered: a reverse leg steers by
    the rear one), a wire layout by the 1983 tug's guide wire.
    """
    camera = layout.kind == 'tape'
    out: dict[str, dict[str, Any]] = {
        'executive': {'srm_map': list(layout.srm_map),
                      'guidance': 'camera' if camera else 'wire'},
        'route_following': {'vehicle': layout.vehicle}}
    if camera:
        out['world'] = {'rear_camera': True}
    if layout.camera_law:
        out['route_following']['camera_law'] = layout.camera_law
    return out


def layout_path(name_or_file: str) -> Path:
    """Load a layout by name (config/layouts/<name>.yaml) or by file path."""
    candidate = Path(name_or_file)
    if candidate.suffix == '.yaml' or candidate.exists():
        return candidate
    return config_dir() / 'layouts' / f'{name_or_file}.yaml'
