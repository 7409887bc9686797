"""Obstacles on the floor: discs a layout places or a command places and removes, ROS-free.

An obstacle is a disc of a diameter (`size`) at (x, y) on the floor, the shape a carton, a post
or a person's legs present to a sonar at bumper height. The floor's obstacles are shared by
every sensor that looks for them (the CONCIC-II's front sonar, agv_nodes/world/sonar.py), and
are the same for either truck's world: the Electruk, which has no sonar, runs into one, and its
bumper (the world's, agv_nodes/world/contact.py's outline) cuts the drive as another truck's
touch does. A layout lists the ones that stand from the start
(`obstacles:`); the world's `world/obstacles` topic places and removes them while it runs, one
JSON command a message:

    {"place": "box", "x": 2.0, "y": 0.0, "size": 0.3}   (a name already placed moves)
    {"remove": "box"}
    {"clear": true}

A command that cannot be used is refused whole, with one line naming the key and the value,
counted by reason and shown in the world's /diagnostics (ObstacleCommands); nothing of it is
applied.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
import json
import math
from typing import Any

SIZE_RANGE = (0.01, 5.0)  # m: a disc the sonar can see, no larger than a room's pillar
FLOOR_RANGE = 1000.0  # m: |x|, |y| of any floor this package lays out


class ObstacleError(ValueError):
    """An obstacle or a command that cannot be used; names the key and the value."""


@dataclass(frozen=True)
class Obstacle:
    """A disc on the floor: its name, centre (m) and diameter (m)."""

    name: str
    x: float
    y: float
    size: float

    @property
    def radius(self) -> float:
        """Half the diameter, m."""
        return self.size / 2.0


def _number(value: Any, key: str, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise ObstacleError(f'key {key}: {value!r} must be a number')
    if not lo <= value <= hi:
        raise ObstacleError(f'key {key}: {value!r} outside {lo}..{hi}')
    return float(value)


def obstacle(spec: Any, where: str = '') -> Obstacle:
    """Return the obstacle a mapping {name|place, x, y, size} describes, or ObstacleError."""
    if not isinstance(spec, dict):
        raise ObstacleError(f'key {where or "obstacle"}: {spec!r} must be a mapping')
    name = spec.get('place', spec.get('name'))
    key = f'{where}.' if where else ''
    if not isinstance(name, str) or not name.strip() or len(name) > 64:
        raise ObstacleError(f'key {key}name: {name!r} must be a name of 1-64 characters')
    extra = set(spec) - {'place', 'name', 'x', 'y', 'size'}
    if extra:
        raise ObstacleError(f'key {key}{sorted(extra)[0]}: unknown (keys: name, x, y, size)')
    return Obstacle(name, _number(spec.get('x'), f'{key}x', -FLOOR_RANGE, FLOOR_RANGE),
                    _number(spec.get('y'), f'{key}y', -FLOOR_RANGE, FLOOR_RANGE),
                    _number(spec.get('size'), f'{key}size', *SIZE_RANGE))


def _inside(outline: list[tuple[float, float]], x: float, y: float) -> bool:
    """Return True when (x, y) is inside or on a convex anticlockwise outline."""
    for i, (x0, y0) in enumerate(outline):
        x1, y1 = outline[(i + 1) % len(outline)]
        if (x1 - x0) * (y - y0) - (y1 - y0) * (x - x0) < 0.0:
            return False
    return True


def _to_segment(x: float, y: float, a: tuple[float, float], b: tuple[float, float]) -> float:
    """Return the distance from (x, y) to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    span = dx * dx + dy * dy
    t = 0.0 if span == 0.0 else min(1.0, max(0.0, ((x - a[0]) * dx + (y - a[1]) * dy) / span))
    return math.hypot(x - a[0] - t * dx, y - a[1] - t * dy)


class Obstacles:
    """The floor's obstacles by name; `changes` counts every place and remove applied."""

    def __init__(self, placed: list[Obstacle] | None = None) -> None:
        self.by_name: dict[str, Obstacle] = {o.name: o for o in placed or []}
        self.changes = 0

    def __iter__(self):
        """Iterate over the obstacles standing now."""
        return iter(list(self.by_name.values()))

    def __len__(self) -> int:
        """Return how many stand now."""
        return len(self.by_name)

    def touching(self, outline: list[tuple[float, float]]) -> Obstacle | None:
        """Return an obstacle that touches or overlaps a convex outline (anticlockwise), if any.

        A disc meets a convex polygon when its centre lies inside it or within its radius of
        one of its edges.
        """
        for item in self.by_name.values():
            if _inside(outline, item.x, item.y) or min(
                    _to_segment(item.x, item.y, outline[i], outline[(i + 1) % len(outline)])
                    for i in range(len(outline))) <= item.radius:
                return item
        return None

    def place(self, item: Obstacle) -> None:
        """Put `item` down (one of its name already there moves)."""
        self.by_name[item.name] = item
        self.changes += 1

    def remove(self, name: str) -> None:
        """Take obstacle `name` away, or ObstacleError naming the ones there are."""
        if name not in self.by_name:
            raise ObstacleError(f'key remove: {name!r} is no obstacle on the floor '
                                f'({", ".join(sorted(self.by_name)) or "none"})')
        del self.by_name[name]
        self.changes += 1

    def apply(self, text: str) -> str:
        """Apply one JSON command (see the module docstring); return what it did, one line."""
        try:
            command = json.loads(text)
        except (ValueError, TypeError) as exc:
            raise ObstacleError(f'not JSON: {text[:60]!r} ({exc})') from None
        if not isinstance(command, dict) or len(set(command) & {'place', 'remove', 'clear'}) != 1:
            raise ObstacleError(f'command {text[:60]!r}: needs one of place, remove, clear')
        if 'place' in command:
            item = obstacle(command)
            self.place(item)
            return f'obstacle {item.name} placed at ({item.x:.3f}, {item.y:.3f}), ' \
                   f'{item.size:.3f} m across'
        if 'remove' in command:
            if set(command) != {'remove'}:
                raise ObstacleError(f'command {text[:60]!r}: remove takes only a name')
            self.remove(command['remove'])
            return f'obstacle {command["remove"]} removed'
        if command != {'clear': True}:
            raise ObstacleError(f'key clear: {command.get("clear")!r} must be true, alone')
        count = len(self.by_name)
        self.by_name.clear()
        self.changes += 1
        return f'{count} obstacle(s) cleared'


class ObstacleCommands:
    """The world/obstacles commands as /diagnostics shows an input (read like a RecordReader).

    Accepted and refused commands are counted, refusals by reason (`not_json`, `bad_command`,
    `unknown_obstacle`), and the last refusal is named.
    """

    lost = 0
    duplicate = ''
    waiting = ''

    def __init__(self, obstacles: Obstacles) -> None:
        self.obstacles = obstacles
        self.accepted = 0
        self.rejects: Counter[str] = Counter()
        self.last_error = ''
        self.stamp_ns: int | None = None

    @property
    def rejected(self) -> int:
        """Commands refused."""
        return sum(self.rejects.values())

    def age_s(self, now_ns: int) -> float:
        """Seconds since the last command applied (inf if none yet)."""
        return float('inf') if self.stamp_ns is None else (now_ns - self.stamp_ns) * 1e-9

    def identity(self) -> str:
        """Anyone may place an obstacle (a test, an operator): no writer is named."""
        return ''

    def take(self, text: str, now_ns: int) -> tuple[bool, str]:
        """Apply one command; return (applied, the line to log)."""
        try:
            line = self.obstacles.apply(text)
        except ObstacleError as exc:
            reason = 'not_json' if str(exc).startswith('not JSON') else \
                'unknown_obstacle' if 'is no obstacle' in str(exc) else 'bad_command'
            self.rejects[reason] += 1
            self.last_error = f'obstacle command refused: {exc}'
            return False, self.last_error
        self.accepted += 1
        self.stamp_ns = now_ns
        return True, line
