"""The floor and the truck as Foxglove scene entities, and the truck's frames.

Frames, as ROS names them (REP 105): `map` (the floor, the layout's own coordinates), `odom`
(where the truck's wheel odometry started: tied to `map` at the world's pose then),
`base_link` (the vehicle reference point: the Electruk's rear axle centre, the CONCIC-II's drive
axle centre), and, fixed on the truck, `marker_lens` (the marker sensor's lens, `sensor.lateral`
right of the front axle centre, looking right: Baker 1983, 5.1, 6.3.2), `camera_front` and
`camera_rear` (the binary camera windows `camera_distance` ahead of and behind the axle,
Rajagopalan 1991, 6.3.4, the rear one facing back). A fleet's truck `<ns>` prefixes each of its
own frames with `<ns>/`.
"""

from __future__ import annotations

import math

from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    FrameTransform,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from agv_nodes.view.frames import TruckShape, frame, sensor_frames
from agv_nodes.world.layout import Layout, Marker

WIRE = Color(r=0.9, g=0.6, b=0.1, a=1.0)
TAPE = Color(r=0.1, g=0.1, b=0.1, a=1.0)
CARD = {'location': Color(r=0.2, g=0.5, b=1.0, a=1.0), 'stop': Color(r=1.0, g=0.3, b=0.2, a=1.0),
        'white': Color(r=0.95, g=0.95, b=0.95, a=1.0)}
BODY = Color(r=0.3, g=0.7, b=0.3, a=0.6)
LENS = Color(r=1.0, g=0.9, b=0.0, a=1.0)
OBSTACLE = Color(r=0.8, g=0.2, b=0.8, a=0.8)
CARD_HEIGHT = 0.08  # m: two rows of 40 mm elements (Baker 1983, 4.3)


def stamp(t: float) -> Timestamp:
    """Return a Foxglove timestamp of `t` s."""
    sec = math.floor(t)
    return Timestamp(sec, min(round((t - sec) * 1e9), 999_999_999))


def yaw_quaternion(heading: float) -> Quaternion:
    """Return the rotation by `heading` about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(heading / 2.0), w=math.cos(heading / 2.0))


def pose(x: float, y: float, heading: float = 0.0, z: float = 0.0) -> Pose:
    """Return a Foxglove pose in the plane."""
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=yaw_quaternion(heading))


def transform(t: float, parent: str, child: str, x: float, y: float,
              heading: float) -> FrameTransform:
    """Return the transform of `child` in `parent` at `t`."""
    return FrameTransform(timestamp=stamp(t), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=x, y=y, z=0.0), rotation=yaw_quaternion(heading))


def floor_entities(layout: Layout, t: float = 0.0) -> list[SceneEntity]:
    """Return the floor in `map`: every wire and tape, every marker card, every station."""
    entities = []
    for pid, path in layout.paths.items():
        points = [Point3(x=float(x), y=float(y), z=0.0) for x, y in path.points[::5]]
        points.append(Point3(x=float(path.points[-1][0]), y=float(path.points[-1][1]), z=0.0))
        tape = path.width > 0.0
        entities.append(SceneEntity(
            timestamp=stamp(t), frame_id='map', id=f'path/{pid}',
            lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, pose=pose(0.0, 0.0),
                                 thickness=path.width if tape else 0.01, scale_invariant=False,
                                 points=points, color=TAPE if tape else WIRE)]))
    for k, m in enumerate(layout.markers):
        entities.append(_card(k, m, t))
    for name in layout.stations:
        cards = [m for m in layout.markers if m.station == name]
        if cards:
            x = sum(m.centre[0] for m in cards) / len(cards)
            y = sum(m.centre[1] for m in cards) / len(cards)
            entities.append(SceneEntity(
                timestamp=stamp(t), frame_id='map', id=f'station/{name}',
                texts=[TextPrimitive(pose=pose(x, y, z=0.3), billboard=True, font_size=14.0,
                                     scale_invariant=True, color=CARD['stop'], text=name)]))
    return entities


def _card(k: int, m: Marker, t: float) -> SceneEntity:
    heading = math.atan2(m.along[1], m.along[0])
    return SceneEntity(
        timestamp=stamp(t), frame_id='map', id=f'marker/{k}',
        cubes=[CubePrimitive(pose=pose(m.centre[0], m.centre[1], heading, z=CARD_HEIGHT / 2.0),
                             size=Vector3(x=0.02 * m.columns, y=0.005, z=CARD_HEIGHT),
                             color=CARD.get(m.kind, CARD['white']))],
        texts=[TextPrimitive(pose=pose(m.centre[0], m.centre[1], z=CARD_HEIGHT + 0.05),
                             billboard=True, font_size=12.0, scale_invariant=True,
                             color=CARD.get(m.kind, CARD['white']), text=m.name)])


def truck_entities(shape: TruckShape, ns: str = '', t: float = 0.0) -> list[SceneEntity]:
    """Return the truck's body in its base_link and its sensors in their own frames."""
    body_x = shape.wheelbase / 2.0  # the body spans the axles
    entities = [SceneEntity(
        timestamp=stamp(t), frame_id=frame(ns, 'base_link'), id=f'{frame(ns, "truck")}/body',
        frame_locked=True,
        cubes=[CubePrimitive(pose=pose(body_x, 0.0, z=0.15),
                             size=Vector3(x=shape.length, y=shape.width, z=0.3), color=BODY)])]
    for name, _x, _y, _h in sensor_frames(shape):
        size = Vector3(x=0.05, y=0.25, z=0.005) if name.startswith('camera') else \
            Vector3(x=0.03, y=0.03, z=0.03)
        entities.append(SceneEntity(
            timestamp=stamp(t), frame_id=frame(ns, name), id=f'{frame(ns, "truck")}/{name}',
            frame_locked=True, cubes=[CubePrimitive(pose=pose(0.0, 0.0), size=size,
                                                    color=LENS)]))
    return entities


def obstacle_entity(name: str, x: float, y: float, size: float, height: float,
                    t: float = 0.0) -> SceneEntity:
    """Return an obstacle in `map`: a post of diameter `size` standing at (x, y)."""
    return SceneEntity(
        timestamp=stamp(t), frame_id='map', id=f'obstacle/{name}',
        cylinders=[CylinderPrimitive(pose=pose(x, y, z=height / 2.0),
                                     size=Vector3(x=size, y=size, z=height),
                                     bottom_scale=1.0, top_scale=1.0, color=OBSTACLE)],
        texts=[TextPrimitive(pose=pose(x, y, z=height + 0.1), billboard=True, font_size=12.0,
                             scale_invariant=True, color=OBSTACLE, text=name)])


def scene(entities: list[SceneEntity]) -> SceneUpdate:
    """Return a scene update of `entities`."""
    return SceneUpdate(entities=entities)
