"""Paths on the floor (guide wires, tapes) and the road signs at tape junctions.

A path is a start pose and straight and arc segments, sampled every `step` m (layout.py loads
them). A road sign (Rajagopalan 1991, 4.3, fig 4.2) is a wider patch of tape before a junction
and the junction's turning branches at right angles, which the camera sees at its window's left
or right edge column. Its branches are drawn by the sign (a length) or are tapes of the layout
(a tape id) that cross the junction at right angles, so a branch can lead back onto the circuit.
A sign with no straight branch (P11, P12, R1) stands where its tape ends (`at: end`): the tape
is cut square across the far edge of the branches, so no tape shows past the crossing and the
straight flag stays clear. Every error names the file, the key and the value.
"""

from dataclasses import dataclass
import math
from pathlib import Path
from typing import Any

import numpy as np


class LayoutError(ValueError):
    """A layout file that cannot be used; names the file, key and value."""


def num(value: Any, file: Path, key: str, lo: float | None = None,
        hi: float | None = None) -> float:
    """Return `value` as a float, or LayoutError naming the file, key and value."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LayoutError(f'{file}: key {key}: {value!r} must be a number')
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise LayoutError(f'{file}: key {key}: {value!r} outside {lo}..{hi}')
    return float(value)


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
    # (start, end) cut square across the tape, not rounded: the camera sees no tape past them
    square_ends: tuple[bool, bool] = (False, False)

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


def build_path(pid: str, start: object, segments: object, step: float, file: Path, key: str,
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


# Road-sign primitives (Rajagopalan 1991, 4.3): which branches a junction offers.
SIGN_BRANCHES = {'P11': ('left',), 'P12': ('right',), 'P21': ('left', 'straight'),
                 'P22': ('right', 'straight'), 'R1': ('left', 'right'),
                 'R2': ('left', 'right', 'straight')}
SIGN_KEYS = ('type', 'path', 'at', 'patch', 'branch')
STUB = 0.35  # m: a drawn branch by default, enough to show at the edge column, not to take
TAKEN = 1.5  # m: the least tape a taken branch needs: the sighting, the turn, the stop after it
ON_JUNCTION = 0.01  # m: a branch tape's centreline passes this close to the crossing
SQUARE_DEG = 3.0  # degrees off a right angle a branch tape may cross at (the spin is 90 deg)


def add_sign(spec: Any, i: int, file: Path, paths: dict[str, Path2D],
             step: float) -> dict[str, Any]:
    """Validate a sign, draw its patch and drawn branches into `paths`; return the sign.

    The sign: type, path, at (the crossing: m along the path, or the path's end), the branch
    tape of each turning side, and `end` (True: the tape ends at the crossing).
    """
    key = f'signs[{i}]'
    if not isinstance(spec, dict):
        raise LayoutError(f'{file}: key {key}: {spec!r} must be a mapping')
    for name in spec:
        if name not in SIGN_KEYS:
            raise LayoutError(f'{file}: key {key}.{name}: unknown (keys: {", ".join(SIGN_KEYS)})')
    kind = spec.get('type')
    if kind not in SIGN_BRANCHES:
        raise LayoutError(f'{file}: key {key}.type: {kind!r} not one of {list(SIGN_BRANCHES)}')
    pid = str(spec.get('path', ''))
    if pid not in paths or paths[pid].width == 0.0:
        raise LayoutError(f'{file}: key {key}.path: {pid!r} is no tape')
    tape = paths[pid]
    straight = 'straight' in SIGN_BRANCHES[kind]
    end = spec.get('at') == 'end'
    if end:
        if tape.closed:
            raise LayoutError(f"{file}: key {key}.at: 'end' but tape {pid!r} is closed")
        # The crossing is half a tape width short of the end: the tape stops flush with the
        # far edge of the branches, as a tape laid up to a crossing one would.
        at = tape.length - tape.width / 2.0
        tape.square_ends = (tape.square_ends[0], True)
    else:
        at = num(spec.get('at'), file, f'{key}.at', 0.3, tape.length)
    after = math.inf if tape.closed else tape.length - at
    if straight and after < TAKEN:
        raise LayoutError(f'{file}: key {key}.at: {spec.get("at")!r} leaves {after:.2f} m of '
                          f'tape after a {kind}, whose straight branch needs {TAKEN} m')
    if not straight and not end:
        raise LayoutError(f'{file}: key {key}.at: {spec.get("at")!r}: a {kind} has no straight '
                          f'branch, so it stands where its tape ends (at: end), not '
                          f'{after:.2f} m before it')
    patch = num(spec.get('patch', 0.15), file, f'{key}.patch', 0.05, 0.5)
    x, y, h = tape.pose_at(at - patch)
    paths[f'sign{i}_patch'] = build_path(f'sign{i}_patch', [x, y, math.degrees(h)],
                                         [{'straight': patch}], step, file, key,
                                         width=tape.width * 1.6)
    # At a tape's end the patch is cut square with it; elsewhere its rounded end lies over the
    # tape running on (the width the straight flag waits to fall, 4.3).
    paths[f'sign{i}_patch'].square_ends = (False, end)
    turning = [b for b in SIGN_BRANCHES[kind] if b != 'straight']
    lengths = _branch_spec(spec.get('branch', STUB), turning, kind, file, f'{key}.branch')
    jx, jy, jh = tape.pose_at(at)
    tapes: dict[str, str] = {}
    for side in turning:
        heading = jh + (math.pi / 2 if side == 'left' else -math.pi / 2)
        value = lengths[side]
        if isinstance(value, str):
            _check_branch_tape(value, paths, (jx, jy, heading), pid, file,
                               f'{key}.branch.{side}')
            tapes[side] = value
            continue
        tapes[side] = f'sign{i}_{side}'
        paths[tapes[side]] = build_path(tapes[side], [jx, jy, math.degrees(heading)],
                                        [{'straight': value}], step, file, key,
                                        width=tape.width)
    drawn = [v for v in lengths.values() if not isinstance(v, str)]
    return {'type': kind, 'path': pid, 'at': at, 'branches': SIGN_BRANCHES[kind],
            'branch': max(drawn, default=0.0), 'tapes': tapes, 'end': end}


def _branch_spec(value: Any, turning: list[str], kind: str, file: Path,
                 key: str) -> dict[str, float | str]:
    """Return each turning side's branch: a length to draw (m) or the id of a layout tape."""
    if not isinstance(value, dict):
        length = num(value, file, key, 0.1, 50.0)
        return {side: length for side in turning}
    out: dict[str, float | str] = {side: STUB for side in turning}
    for side, item in value.items():
        if side not in turning:
            raise LayoutError(f'{file}: key {key}.{side}: a {kind} turns only '
                              f'{" and ".join(turning)}')
        out[side] = item if isinstance(item, str) else num(item, file, f'{key}.{side}', 0.1, 50.0)
    return out


def _check_branch_tape(tid: str, paths: dict[str, Path2D], junction: tuple[float, float, float],
                       own: str, file: Path, key: str) -> None:
    """Check a named branch: a tape across the junction at right angles, TAKEN m on its side."""
    if tid not in paths or paths[tid].width == 0.0 or tid == own:
        raise LayoutError(f'{file}: key {key}: {tid!r} is no other tape of the layout')
    tape = paths[tid]
    x, y, heading = junction
    s, lateral, tangent = tape.project(x, y)
    if abs(lateral) > ON_JUNCTION:
        raise LayoutError(f'{file}: key {key}: {tid!r} passes {abs(lateral):.3f} m from the '
                          f'crossing at ({x:.3f}, {y:.3f}); it must cross within {ON_JUNCTION} m')
    cos = math.cos(tangent - heading)
    if abs(cos) < math.cos(math.radians(SQUARE_DEG)):
        off = math.degrees(math.acos(min(1.0, abs(cos))))
        raise LayoutError(f'{file}: key {key}: {tid!r} crosses at {off:.1f} deg to the branch; '
                          f'the truck spins a quarter turn, so it must be within {SQUARE_DEG} deg')
    run = math.inf if tape.closed else (tape.length - s if cos > 0 else s)
    if run < TAKEN:
        raise LayoutError(f'{file}: key {key}: {tid!r} runs {run:.2f} m from the crossing on the '
                          f'branch side; a branch to take needs {TAKEN} m')


def branch_ends(signs: list[dict[str, Any]], paths: dict[str, Path2D]) -> list[str]:
    """Return one line per sign: where it stands and where each turning branch leads.

    A branch leads onto another tape when its far end lies on one (a join), else to a dead end
    (the truck stops there and reverses out along it); shorter than TAKEN m it is only a stub.
    """
    lines = []
    for n, sign in enumerate(signs):
        x, y, _h = paths[sign['path']].pose_at(sign['at'])
        where = 'at its end' if sign['end'] else f'{sign["at"]:.2f} m along'
        parts = []
        for side, tid in sign['tapes'].items():
            tape = paths[tid]
            if not tid.startswith('sign'):
                parts.append(f'{side}: tape {tid}')
                continue
            if tape.length < TAKEN:
                parts.append(f'{side}: {tape.length:.2f} m stub (not to be taken)')
                continue
            fx, fy, _ = tape.pose_at(tape.length)
            onto = [p.id for p in paths.values() if p.id != tid and p.width > 0
                    and not p.id.startswith(f'sign{n}_') and abs(p.project(fx, fy)[1]) < 0.03]
            parts.append(f'{side}: {tape.length:.2f} m, ' + (f'joins {onto[0]}' if onto else
                                                              'dead end'))
        lines.append(f'{sign["type"]:3} on {sign["path"]} {where} ({x:.2f}, {y:.2f}): '
                     + '; '.join(parts))
    return lines
