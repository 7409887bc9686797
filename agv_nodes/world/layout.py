"""World layouts (config/layouts/*.yaml): guide wires or tape, markers on stands, workstations.

A path (guide wire or optical tape) is a start pose and straight and arc segments, sampled every
`step` m. Markers are placed by (path, distance along it), the card facing the path from the sensor
side at the standoff (Baker 1983, 4.4 and 5.1: 300 mm from the lens; the route held to +-1 cm, this
reproduction's goal: the thesis states none). Every error names the file, the key and the value.
"""

from dataclasses import dataclass, field
import math
from pathlib import Path
from typing import Any

import numpy as np

from agv_nodes.markers import LOCATION_PATTERNS, STOP_STRIP, WHITE_CARD
from agv_nodes.package_share import config_dir, read_mapping


class LayoutError(ValueError):
    """A layout file that cannot be used; names the file, key and value."""


@dataclass
class Path2D:
    """A route on the floor: a guide wire or a tape centreline, as a dense polyline."""

    id: str
    points: np.ndarray  # (n, 2)
    s: np.ndarray  # (n,) distance along the path at each point
    headings: np.ndarray  # (n,) tangent heading at each point, rad
    width: float = 0.0  # tape width (m); 0 for a wire
    current: float = 1.0  # relative line current (wires)
    closed: bool = False

    @property
    def length(self) -> float:
        """Total length, m."""
        return float(self.s[-1])

    def pose_at(self, s: float) -> tuple[float, float, float]:
        """(x, y, heading) at distance s along the path (clamped to its ends)."""
        s = min(max(s, 0.0), self.length)
        i = int(np.searchsorted(self.s, s, side='right')) - 1
        i = min(max(i, 0), len(self.s) - 2)
        seg = self.s[i + 1] - self.s[i]
        t = 0.0 if seg <= 0 else (s - self.s[i]) / seg
        x, y = self.points[i] + t * (self.points[i + 1] - self.points[i])
        h0, h1 = self.headings[i], self.headings[i + 1]
        dh = math.atan2(math.sin(h1 - h0), math.cos(h1 - h0))
        return float(x), float(y), float(h0 + t * dh)

    def project(self, x: float, y: float) -> tuple[float, float, float]:
        """(s, signed lateral offset, + = left of the path, heading) of the nearest point."""
        p = np.array([x, y])
        a = self.points[:-1]
        d = self.points[1:] - a
        dd = np.einsum('ij,ij->i', d, d)
        t = np.clip(np.einsum('ij,ij->i', p - a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        foot = a + t[:, None] * d
        dist2 = np.einsum('ij,ij->i', p - foot, p - foot)
        i = int(np.argmin(dist2))
        seg = math.sqrt(dd[i])
        heading = math.atan2(d[i, 1], d[i, 0])
        rel = p - foot[i]
        lateral = -math.sin(heading) * rel[0] + math.cos(heading) * rel[1]
        return float(self.s[i] + t[i] * seg), lateral, heading


def build_path(pid: str, start: list, segments: list, step: float, file: Path, key: str,
               width: float = 0.0, current: float = 1.0) -> Path2D:
    """Sample a start pose + straight/arc segments into a polyline."""
    if not (isinstance(start, list) and len(start) == 3
            and all(isinstance(v, (int, float)) for v in start)):
        raise LayoutError(f'{file}: key {key}.start: {start!r} must be [x, y, heading_deg]')
    x, y, h = float(start[0]), float(start[1]), math.radians(float(start[2]))
    pts, hs = [(x, y)], [h]
    if not isinstance(segments, list) or not segments:
        raise LayoutError(f'{file}: key {key}.segments: {segments!r} must be a non-empty list')
    for j, seg in enumerate(segments):
        where = f'{key}.segments[{j}]'
        if not isinstance(seg, dict):
            raise LayoutError(f'{file}: key {where}: {seg!r} must be a mapping')
        if 'straight' in seg:
            length = seg['straight']
            if not isinstance(length, (int, float)) or length <= 0:
                raise LayoutError(f'{file}: key {where}.straight: {length!r} must be > 0 m')
            n = max(1, math.ceil(length / step))
            for k in range(1, n + 1):
                d = length * k / n
                pts.append((x + d * math.cos(h), y + d * math.sin(h)))
                hs.append(h)
            x, y = pts[-1]
        elif 'arc' in seg:
            radius, angle = seg['arc'], seg.get('angle')
            if not isinstance(radius, (int, float)) or radius <= 0:
                raise LayoutError(f'{file}: key {where}.arc: {radius!r} must be a radius > 0 m')
            if not isinstance(angle, (int, float)) or angle == 0:
                raise LayoutError(f'{file}: key {where}.angle: {angle!r} must be non-zero '
                                  'degrees (+ = left)')
            turn = math.radians(angle)
            sign = 1.0 if turn > 0 else -1.0
            cx, cy = x - sign * radius * math.sin(h), y + sign * radius * math.cos(h)
            n = max(2, math.ceil(abs(turn) * radius / step))
            for k in range(1, n + 1):
                hk = h + turn * k / n
                pts.append((cx + sign * radius * math.sin(hk), cy - sign * radius * math.cos(hk)))
                hs.append(hk)
            x, y = pts[-1]
            h = h + turn
        else:
            raise LayoutError(f'{file}: key {where}: {seg!r} needs "straight" or "arc"')
    points = np.array(pts)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    closed = bool(np.linalg.norm(points[-1] - points[0]) < 1e-6)
    return Path2D(pid, points, s, np.array(hs), width, current, closed)


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

    @property
    def name(self) -> str:
        """Short label for reports: L0..L3, <station>.<n> for stop markers, W."""
        if self.kind == 'location':
            return f'L{self.identity}'
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


_TOP_KEYS = {'layout', 'description', 'vehicle', 'kind', 'wires', 'tapes', 'markers',
             'stations', 'start', 'sensor', 'rig', 'route_limit', 'step', 'signs', 'srm_map'}
# Road-sign primitives (Rajagopalan 1991, 4.3): which branches a junction offers.
SIGN_BRANCHES = {'P11': ('left',), 'P12': ('right',), 'P21': ('left', 'straight'),
                 'P22': ('right', 'straight'), 'R1': ('left', 'right'),
                 'R2': ('left', 'right', 'straight')}


def _num(value: Any, file: Path, key: str, lo: float | None = None,
         hi: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LayoutError(f'{file}: key {key}: {value!r} must be a number')
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise LayoutError(f'{file}: key {key}: {value!r} outside {lo}..{hi}')
    return float(value)


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
    signs = [_add_sign(spec, i, file, paths, step) for i, spec in enumerate(doc.get('signs')
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
        srm_map=_srm_map(doc.get('srm_map') or [], file))
    if kind == 'rig':
        _check_rig(layout, file)
    return layout


def _load_marker(spec: Any, i: int, file: Path, paths: dict[str, Path2D],
                 stations: dict[str, Station], card: dict[str, float],
                 sensor_lateral: float) -> Marker:
    key = f'markers[{i}]'
    if not isinstance(spec, dict):
        raise LayoutError(f'{file}: key {key}: {spec!r} must be a mapping')
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
               station=station, conveyor=conveyor)
    x, y, h = (float(v) for v in path.pose_at(at))
    reach = sensor_lateral + m.standoff
    m.centre = (x + math.sin(h) * reach, y - math.cos(h) * reach)
    # The card faces back toward the path, turned by `yaw` about the vertical.
    m.normal = (-math.sin(h + m.yaw), math.cos(h + m.yaw))
    m.along = (math.cos(h + m.yaw), math.sin(h + m.yaw))
    return m


def _add_sign(spec: Any, i: int, file: Path, paths: dict[str, Path2D],
              step: float) -> dict[str, Any]:
    """Draw a road sign on a tape: a wider patch before the junction, then the branches.

    Each turning branch is a tape at right angles (the camera sees the width jump, then the branch
    at column 0 or 127), `branch` m long (0.35 m).
    """
    key = f'signs[{i}]'
    if not isinstance(spec, dict):
        raise LayoutError(f'{file}: key {key}: {spec!r} must be a mapping')
    kind = spec.get('type')
    if kind not in SIGN_BRANCHES:
        raise LayoutError(f'{file}: key {key}.type: {kind!r} not one of {list(SIGN_BRANCHES)}')
    pid = str(spec.get('path', ''))
    if pid not in paths or paths[pid].width == 0.0:
        raise LayoutError(f'{file}: key {key}.path: {pid!r} is no tape')
    tape = paths[pid]
    at = _num(spec.get('at'), file, f'{key}.at', 0.3, tape.length)
    patch = _num(spec.get('patch', 0.15), file, f'{key}.patch', 0.05, 0.5)
    # A short stub shows the branch to the camera; a long one is a branch the truck can take.
    branch_length = _num(spec.get('branch', 0.35), file, f'{key}.branch', 0.1, 50.0)
    x, y, h = tape.pose_at(at - patch)
    paths[f'sign{i}_patch'] = build_path(f'sign{i}_patch', [x, y, math.degrees(h)],
                                         [{'straight': patch}], step, file, key,
                                         width=tape.width * 1.6)
    jx, jy, jh = tape.pose_at(at)
    for branch in SIGN_BRANCHES[kind]:
        if branch == 'straight':
            continue
        turn = math.pi / 2 if branch == 'left' else -math.pi / 2
        paths[f'sign{i}_{branch}'] = build_path(
            f'sign{i}_{branch}', [jx, jy, math.degrees(jh + turn)],
            [{'straight': branch_length}], step,
            file, key, width=tape.width)
    return {'type': kind, 'path': pid, 'at': at, 'branches': SIGN_BRANCHES[kind],
            'branch': branch_length}


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


def layout_parameters(layout: Layout) -> dict[str, dict[str, Any]]:
    """Return what a layout sets in its truck's nodes: the route map, route following's vehicle."""
    return {'executive': {'srm_map': list(layout.srm_map)},
            'route_following': {'vehicle': layout.vehicle}}


def layout_path(name_or_file: str) -> Path:
    """Load a layout by name (config/layouts/<name>.yaml) or by file path."""
    candidate = Path(name_or_file)
    if candidate.suffix == '.yaml' or candidate.exists():
        return candidate
    return config_dir() / 'layouts' / f'{name_or_file}.yaml'
