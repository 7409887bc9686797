"""The world's pictures: route, marker cards and obstacles (latched), the pose, camera frames."""

import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
import numpy as np
from sensor_msgs.msg import Image
from visualization_msgs.msg import Marker, MarkerArray

from agv_nodes.world.layout import Layout


def _orientation(pose: PoseStamped, heading: float) -> None:
    pose.pose.orientation.z = math.sin(heading / 2)
    pose.pose.orientation.w = math.cos(heading / 2)


def pose_message(x: float, y: float, heading: float, stamp: Time) -> PoseStamped:
    """world/pose: the vehicle reference point in the map frame."""
    msg = PoseStamped()
    msg.header.stamp = stamp
    msg.header.frame_id = 'map'
    msg.pose.position.x, msg.pose.position.y = x, y
    _orientation(msg, heading)
    return msg


def camera_image(frame: np.ndarray, name: str, stamp: Time) -> Image:
    """hw/camera/<name>: a binary frame (1 = dark tape) as mono8, tape dark = 0."""
    img = Image()
    img.header.stamp = stamp
    img.header.frame_id = f'camera_{name}'
    img.height, img.width = frame.shape
    img.encoding = 'mono8'
    img.step = img.width
    img.data = ((1 - frame) * 255).astype('uint8').tobytes()
    return img


def _card(k: int, m) -> list[Marker]:
    card = Marker(ns='cards', id=k, type=Marker.CUBE, action=Marker.ADD)
    card.header.frame_id = 'map'
    card.pose.position.x, card.pose.position.y = float(m.centre[0]), float(m.centre[1])
    card.pose.position.z = 0.5
    yaw = math.atan2(m.along[1], m.along[0])
    card.pose.orientation.z, card.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    card.scale.x, card.scale.y, card.scale.z = m.columns * 0.02, 0.01, 0.08
    card.color.a = 1.0
    card.color.r = 1.0 if m.kind == 'stop' else 0.2
    card.color.g = 1.0 if m.kind == 'location' else 0.2
    label = Marker(ns='labels', id=k, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD, text=m.name)
    label.header.frame_id = 'map'
    label.pose = card.pose
    label.pose.position.z = 0.8
    label.scale.z = 0.2
    label.color.a = label.color.r = label.color.g = label.color.b = 1.0
    return [card, label]


def layout_messages(layout: Layout) -> tuple[Path, MarkerArray]:
    """Build world/route (every wire and tape as one path) and world/markers (paths and cards)."""
    path = Path()
    path.header.frame_id = 'map'
    markers = MarkerArray()
    for k, p in enumerate(layout.paths.values()):
        strip = Marker(ns='paths', id=k, type=Marker.LINE_STRIP, action=Marker.ADD)
        strip.header.frame_id = 'map'
        strip.scale.x = max(p.width, 0.01)
        strip.color.a, strip.color.r, strip.color.g, strip.color.b = 1.0, 0.9, 0.6, 0.1
        strip.pose.orientation.w = 1.0
        for (x, y), h in zip(p.points[::5], p.headings[::5], strict=True):
            pose = PoseStamped()
            pose.header.frame_id = 'map'
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            _orientation(pose, float(h))
            path.poses.append(pose)
            strip.points.append(Point(x=float(x), y=float(y)))
        markers.markers.append(strip)
    for k, m in enumerate(layout.markers):
        markers.markers.extend(_card(k, m))
    return path, markers


OBSTACLE_HEIGHT = 0.5  # m: drawn as a post; the sonar sees a disc at its own height


def obstacle_markers(obstacles) -> MarkerArray:
    """Build world/obstacle_markers: a DELETEALL, then each standing obstacle as a cylinder.

    Sent whole on every change (latched), so a viewer joining late sees the floor as it is and
    a removed obstacle disappears. The marker's `text` carries the obstacle's name.
    """
    out = MarkerArray()
    clear = Marker(ns='obstacles', action=Marker.DELETEALL)
    clear.header.frame_id = 'map'
    out.markers.append(clear)
    for k, item in enumerate(sorted(obstacles, key=lambda o: o.name)):
        post = Marker(ns='obstacles', id=k, type=Marker.CYLINDER, action=Marker.ADD,
                      text=item.name)
        post.header.frame_id = 'map'
        post.pose.position.x, post.pose.position.y = float(item.x), float(item.y)
        post.pose.position.z = OBSTACLE_HEIGHT / 2.0
        post.pose.orientation.w = 1.0
        post.scale.x = post.scale.y = float(item.size)
        post.scale.z = OBSTACLE_HEIGHT
        post.color.a, post.color.r, post.color.g, post.color.b = 0.8, 0.8, 0.2, 0.8
        out.markers.append(post)
    return out
