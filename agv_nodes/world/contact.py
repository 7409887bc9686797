"""Where trucks touch: each truck's footprint on the floor, and whether two overlap, ROS-free.

The footprint is the Electruk's body as a rectangle (its outline is assumed: the world's
`electruk.width`, `front_overhang` and `rear_overhang`) around the reference point, the rear
axle centre. Two convex outlines overlap unless some edge of one separates them (the
separating axis theorem); touching counts as overlapping.
"""

from __future__ import annotations

import math

from agv_nodes.world.settings import ElectrukParams

Point = tuple[float, float]


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


def overlap(a: list[Point], b: list[Point]) -> bool:
    """Return True when two convex outlines (anticlockwise corners) touch or overlap."""
    return not (_separated(a, b) or _separated(b, a))
