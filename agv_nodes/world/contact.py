"""Where trucks touch: each truck's footprint on the floor, and whether two overlap, ROS-free.

The footprint is the Electruk's body as a rectangle (its outline is assumed: the world's
`electruk.width`, `front_overhang` and `rear_overhang`) around the reference point, the rear
axle centre. Two convex outlines overlap unless some edge of one separates them (the
separating axis theorem); touching counts as overlapping.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math

from agv_nodes.world.settings import ElectrukParams

Point = tuple[float, float]
Pose = tuple[float, float, float, float]  # x, y, heading, speed


def footprint(x: float, y: float, heading: float, p: ElectrukParams) -> list[Point]:
    """Return the body's corners, anticlockwise, for the rear axle centre at (x, y)."""
    c, s = math.cos(heading), math.sin(heading)
    half = p.width / 2.0
    return [(x + a * c - b * s, y + a * s + b * c)
            for a, b in ((-p.rear_overhang, -half), (p.wheelbase + p.front_overhang, -half),
                         (p.wheelbase + p.front_overhang, half), (-p.rear_overhang, half))]


def _separated(a: list[Point], b: list[Point]) -> bool:
    """Return True when an edge of `a` has all of `b` strictly outside it."""
    for i, (x0, y0) in enumerate(a):
        x1, y1 = a[(i + 1) % len(a)]
        nx, ny = y1 - y0, x0 - x1  # the outward normal of an anticlockwise edge
        reach = max(nx * (px - x0) + ny * (py - y0) for px, py in a)
        if min(nx * (px - x0) + ny * (py - y0) for px, py in b) > reach:
            return True
    return False


def bounding_circle(x: float, y: float, heading: float, p: ElectrukParams
                    ) -> tuple[float, float, float]:
    """Return (cx, cy, r): a circle about the body, for the rear axle centre at (x, y).

    The rectangle's centre and half its diagonal, widened by a micrometre: a test that rounding
    can never make tighter than the body, so it only spares the edge tests of bodies apart.
    """
    along = (p.wheelbase + p.front_overhang - p.rear_overhang) / 2.0
    half_length = (p.wheelbase + p.front_overhang + p.rear_overhang) / 2.0
    return (x + along * math.cos(heading), y + along * math.sin(heading),
            math.hypot(half_length, p.width / 2.0) + 1e-6)


def overlap(a: list[Point], b: list[Point]) -> bool:
    """Return True when two convex outlines (anticlockwise corners) touch or overlap."""
    return not (_separated(a, b) or _separated(b, a))


@dataclass(frozen=True)
class Collision:
    """Two trucks that touched, and when."""

    time: float  # simulated s
    trucks: tuple[str, str]
    speeds: tuple[float, float]  # m/s of each at the contact


class ContactWatch:
    """Trucks on one floor: which touch now, and each new contact as a Collision.

    A pair that stays in contact is one collision, not one per sample; once apart and touching
    again it is a new one. `bodies` maps each truck to its pose (x, y, heading, speed) and
    body outline parameters.
    """

    def __init__(self, names: Sequence[str]) -> None:
        self.names = list(names)
        self.touching: set[tuple[str, str]] = set()
        self.collisions: list[Collision] = []

    def contacts(self, bodies: Mapping[str, tuple[Pose, ElectrukParams]]
                 ) -> set[tuple[str, str]]:
        """Return the pairs (in `names` order) whose footprints touch or overlap.

        A pair whose circles about the bodies (`bounding_circle`) are apart cannot touch; only
        the others are tested edge by edge, which a floor's trucks mostly are not. Only the
        circles whose spans along x overlap are compared (sweep and prune).
        """
        names = self.names
        # in order of their left ends: a later circle whose left end is past this one's right
        # end is apart from it, and so is every circle after that
        circles = sorted((cx - r, cx, cy, r, k) for k, (cx, cy, r) in enumerate(
            bounding_circle(*bodies[name][0][:3], bodies[name][1]) for name in names))
        shapes: dict[str, list[Point]] = {}
        out = set()
        for i, (_left, ax, ay, ar, ka) in enumerate(circles):
            right = ax + ar
            for left, bx, by, br, kb in circles[i + 1:]:
                if left > right:
                    break
                if (ax - bx) ** 2 + (ay - by) ** 2 > (ar + br) ** 2:
                    continue
                a, b = (names[ka], names[kb]) if ka < kb else (names[kb], names[ka])
                for name in (a, b):
                    if name not in shapes:
                        pose, p = bodies[name]
                        shapes[name] = footprint(*pose[:3], p)
                if overlap(shapes[a], shapes[b]):
                    out.add((a, b))
        return out

    def check(self, bodies: Mapping[str, tuple[Pose, ElectrukParams]],
              now: float) -> list[Collision]:
        """Return the contacts new since the last check (kept in `collisions` too)."""
        touching = self.contacts(bodies)
        new = [Collision(now, (a, b), (bodies[a][0][3], bodies[b][0][3]))
               for a, b in sorted(touching - self.touching)]
        self.touching = touching
        self.collisions.extend(new)
        return new
