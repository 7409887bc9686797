"""One truck's frames: `map -> odom -> base_link -> sensors`, from its wheels and the world.

ROS-free, for the live view (agv_nodes/view/live.py) and the recorder, which writes the same
frames into bags. `odom` is tied to `map` at the world's pose when the first wheel record comes
(a truck at rest at start-up: exactly; one that joins while the truck moves: where the world's
last pose was); `base_link` moves in `odom` by the wheel counters alone (WheelDeadReckoning);
the sensors' frames are fixed on the truck (agv_nodes.view.scene.sensor_frames).
"""

from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any

from agv_nodes.view.odometry import PlanarPose, WheelDeadReckoning
from agv_nodes.world.settings import WorldParams

Transform = tuple[str, str, float, float, float]  # parent, child, x, y, heading


@dataclass(frozen=True)
class TruckShape:
    """What the scene draws of a truck, and where its sensors sit (m)."""

    vehicle: str  # 'electruk' | 'concic2'
    length: float
    width: float
    wheelbase: float  # axle to the front axle / front camera window
    lens_lateral: float  # the marker lens right of the front axle centre
    camera_distance: float


def truck_shape(vehicle: str, lens_lateral: float, world: WorldParams) -> TruckShape:
    """Return what a view draws of the layout's vehicle, from the world's parameters."""
    if vehicle == 'concic2':
        c = world.concic2
        return TruckShape('concic2', 2.0 * c.camera_distance, c.wheel_span + 0.1, 0.0,
                          0.0, c.camera_distance)
    e = world.electruk
    return TruckShape('electruk', e.wheelbase + e.front_overhang + e.rear_overhang, e.width,
                      e.wheelbase, lens_lateral, 0.0)


def track_of(shape: TruckShape, world: WorldParams) -> float:
    """Return m between the driven wheels of the shape's vehicle."""
    return world.concic2.wheel_span if shape.vehicle == 'concic2' else world.electruk.track


def frame(ns: str, name: str) -> str:
    """Return a truck's frame name (prefixed with its namespace in a fleet)."""
    return f'{ns.strip("/")}/{name}' if ns.strip('/') else name


def sensor_frames(shape: TruckShape) -> list[tuple[str, float, float, float]]:
    """Return the truck's fixed frames in base_link: (name, x, y, heading)."""
    if shape.vehicle == 'concic2':
        d = shape.camera_distance
        return [('camera_front', d, 0.0, 0.0), ('camera_rear', -d, 0.0, math.pi)]
    return [('marker_lens', shape.wheelbase, -shape.lens_lateral, -math.pi / 2.0)]




class TruckFrames:
    """The frames of the truck in namespace `ns` (its own prefixed with it in a fleet)."""

    def __init__(self, ns: str, shape: TruckShape, track: float) -> None:
        self.ns, self.shape = ns.strip('/'), shape
        self.odometry = WheelDeadReckoning(track)
        self.anchor: PlanarPose | None = None  # map -> odom
        self.truth: PlanarPose | None = None  # the world's last pose of base_link in map

    def name(self, frame_name: str) -> str:
        """Return this truck's frame `frame_name` (namespace-prefixed in a fleet)."""
        return frame(self.ns, frame_name)

    def on_truth(self, x: float, y: float, heading: float) -> PlanarPose:
        """Take the world's pose of the truck (ground truth, `map`)."""
        self.truth = PlanarPose(x, y, heading)
        return self.truth

    def on_wheels(self, fields: dict[str, Any]) -> PlanarPose | None:
        """Take one wheel_odometry record; return base_link in odom (None: not tied to map yet)."""
        if self.anchor is None:
            if self.truth is None:
                return None
            self.anchor = PlanarPose(self.truth.x, self.truth.y, self.truth.heading)
        return self.odometry.update(fields)

    def moving(self) -> list[Transform]:
        """Return map -> odom and odom -> base_link as they stand ([] before the first wheel)."""
        a, p = self.anchor, self.odometry.pose
        if a is None:
            return []
        return [('map', self.name('odom'), a.x, a.y, a.heading),
                (self.name('odom'), self.name('base_link'), p.x, p.y, p.heading)]

    def fixed(self) -> list[Transform]:
        """Return base_link -> each sensor (static)."""
        return [(self.name('base_link'), self.name(n), x, y, h)
                for n, x, y, h in sensor_frames(self.shape)]
