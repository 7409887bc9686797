"""The CONCIC-II's front ultrasonic sensor (Rajagopalan 1991, 6.3, 6.3.11, 2.2.4.4), ROS-free.

A Polaroid-type ranging sonar at the front of the truck (Fig. 6.1), `mount` m ahead of the axle
centre, looking along the truck's heading. Each ping reports the first echo: the nearest point
of any obstacle (a disc, agv_nodes/world/obstacles.py) inside the beam, a cone of `beam` degrees
(full angle) and `max_range` m. Nearer than `min_range` (the transmit pulse and its blanking,
2.2.4.4: 27.5 cm) no echo can be timed, and the reading says so (-inf, REP 117's "too close");
no echo within range reads +inf. A timed echo carries Gaussian noise of `noise` m rms, seeded.

The first echo of a disc inside a cone: if the direction to the disc's centre lies inside the
cone, the nearest point of the disc (centre distance less the radius) does too; otherwise the
nearest point of disc and cone together lies on one of the cone's two edge rays (the circle's
points nearer the sensor than the rays' crossings lie outside the cone), so it is the first
crossing of an edge ray with the circle.
"""

from __future__ import annotations

from collections.abc import Iterable
import math
import random

from agv_nodes.world.obstacles import Obstacle
from agv_nodes.world.settings import SonarParams


def disc_echo(sx: float, sy: float, heading: float, half_angle: float, cx: float, cy: float,
              radius: float) -> float | None:
    """Return the distance (m) from (sx, sy) to the nearest point of a disc inside the cone.

    The cone looks along `heading` (rad), `half_angle` (rad, below pi/2) either side; None when
    no part of the disc lies inside it. A sensor inside the disc reads 0.
    """
    dx, dy = cx - sx, cy - sy
    dist = math.hypot(dx, dy)
    if dist <= radius:
        return 0.0
    bearing = math.atan2(dy, dx) - heading
    bearing = math.atan2(math.sin(bearing), math.cos(bearing))
    if abs(bearing) <= half_angle:
        return dist - radius
    best: float | None = None
    for side in (1.0, -1.0):
        ray = heading + side * half_angle
        along = dx * math.cos(ray) + dy * math.sin(ray)
        if along <= 0.0:
            continue
        across2 = dist * dist - along * along
        if across2 > radius * radius:
            continue
        hit = along - math.sqrt(radius * radius - across2)
        best = hit if best is None else min(best, hit)
    return best


class Sonar:
    """The front sonar: first echoes of the floor's obstacles (see the module docstring)."""

    def __init__(self, params: SonarParams, seed: int) -> None:
        self.p = params
        # Its own stream, so the sonar's pings leave every other sensor's noise as it was.
        self.rng = random.Random(f'sonar-{seed}')

    def position(self, x: float, y: float, heading: float) -> tuple[float, float]:
        """Return the transducer's floor position for the axle centre at (x, y)."""
        return x + self.p.mount * math.cos(heading), y + self.p.mount * math.sin(heading)

    def first_echo(self, x: float, y: float, heading: float,
                   obstacles: Iterable[Obstacle]) -> float | None:
        """Return the true distance (m) of the first echo for the axle at (x, y), or None."""
        sx, sy = self.position(x, y, heading)
        half = math.radians(self.p.beam) / 2.0
        best: float | None = None
        for item in obstacles:
            if (d := disc_echo(sx, sy, heading, half, item.x, item.y, item.radius)) is not None:
                best = d if best is None else min(best, d)
        return best

    def ping(self, x: float, y: float, heading: float, obstacles: Iterable[Obstacle]) -> float:
        """Return one reading (m): the first echo with noise, -inf too close, +inf none."""
        echo = self.first_echo(x, y, heading, obstacles)
        if echo is None or echo > self.p.max_range:
            return math.inf
        if echo < self.p.min_range:
            return -math.inf
        noisy = echo + self.rng.gauss(0.0, self.p.noise) if self.p.noise > 0 else echo
        return min(max(noisy, self.p.min_range), self.p.max_range)
