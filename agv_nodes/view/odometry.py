"""Dead reckoning from the wheel odometry record, as the truck itself could know its pose.

The 1983 truck counts distance, not pose (Baker 1983, 6.3.3: navigation's odometry is the
mean of the driven wheels' travel), so the pose a viewer shows in the `odom` frame is what the
same wheel counters give when integrated in the plane: the two driven wheels `track` apart, the
heading from the difference of their travel (a differential drive about the driven axle's
centre: the Electruk's rear axle, the CONCIC-II's drive axle). It drifts as wheel odometry does
(slip, rounding of the mm counters); the viewer ties `odom` to `map` at the start (the world's
pose then) and the gap to the ground truth is what a real truck would carry.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from agv_nodes.odometry import counter_step


@dataclass
class PlanarPose:
    """A pose in the plane: x, y (m), heading (rad), and the speeds it was reached with."""

    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    speed: float = 0.0  # m/s, along the heading
    yaw_rate: float = 0.0  # rad/s


class WheelDeadReckoning:
    """Integrates wheel_odometry records (wrapping u16 mm counters) into a PlanarPose."""

    def __init__(self, track: float, start: PlanarPose | None = None) -> None:
        if track <= 0.0:
            raise ValueError(f'track {track!r}: must be > 0 m')
        self.track = track
        self.pose = start or PlanarPose()
        self._last: tuple[int, int] | None = None

    def update(self, fields: dict[str, int]) -> PlanarPose:
        """Take one wheel_odometry record (left/right distance mm and speed mm/s)."""
        left, right = fields['left_distance'], fields['right_distance']
        p = self.pose
        if self._last is not None:
            dl = counter_step(self._last[0], left) / 1000.0
            dr = counter_step(self._last[1], right) / 1000.0
            ds, dh = (dl + dr) / 2.0, (dr - dl) / self.track
            mid = p.heading + dh / 2.0  # the chord of the arc the axle centre drove
            p.x += ds * math.cos(mid)
            p.y += ds * math.sin(mid)
            p.heading = math.atan2(math.sin(p.heading + dh), math.cos(p.heading + dh))
        self._last = (left, right)
        vl, vr = fields['left_speed'] / 1000.0, fields['right_speed'] / 1000.0
        p.speed, p.yaw_rate = (vl + vr) / 2.0, (vr - vl) / self.track
        return p
