"""live_view: watch a running graph in Foxglove, and the trucks' odometry and frames in ROS.

One process beside the graph (`agv-launch --foxglove`, or `ros2 run agv_nodes live_view`
against any running graph). It serves a Foxglove WebSocket (foxglove-sdk) on 127.0.0.1 with:

- `/scene`: the floor (wires and tape, marker cards, stations, the obstacles standing, as the
  world's latched `world/obstacle_markers` gives them) and each truck's body with its marker
  lens or camera windows (agv_nodes.view.scene), re-sent every `scene_period` and on a change;
- `/tf`: the frames `map -> odom -> base_link -> marker_lens | camera_front | camera_rear` of
  each truck (its own prefixed with its namespace in a fleet);
- `[/<ns>]/decoded/<record topic>`: every record decoded, with the reader's verdict
  (agv_nodes.records.decoded, JSON with its schema from msg_schemas/);
- `[/<ns>]/hw/camera/front|rear`: the binary camera frames; `[/<ns>]/reports`: the task
  reports and the world's events as log lines; `[/<ns>]/odom`, `[/<ns>]/world/odom`: the
  odometry below.

In ROS it publishes, for each truck, `odom` (nav_msgs/Odometry, frame `odom`): the pose the
truck's own wheel odometry gives (agv_nodes.view.odometry), with `odom` tied to `map` at the
world's pose when the first wheel record came; and `world/odom`: the world's ground truth
(frame `map`), beside it. Where tf2_msgs can be imported (a ROS install) it also publishes the
frames on `/tf`; the recorder writes them into bags either way (rosbags knows the type).
"""

from __future__ import annotations

from functools import partial
import importlib
import math
import sys
from typing import Any

import foxglove
from foxglove.channels import (
    FrameTransformsChannel,
    LogChannel,
    RawImageChannel,
    SceneUpdateChannel,
)
from foxglove.messages import (
    FrameTransforms,
    Log,
    LogLevel,
    RawImage,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
)
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import Image
from std_msgs.msg import String, UInt8MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from agv_nodes import qos
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.records import codec
from agv_nodes.records.decoded import decoded, decoded_topic, json_schema
from agv_nodes.records.ports import RecordReader
from agv_nodes.ros_ports import record_bytes
from agv_nodes.settings import settings_class
from agv_nodes.view.frames import TruckFrames, TruckShape, frame, track_of, truck_shape
from agv_nodes.view.odometry import PlanarPose
from agv_nodes.view.scene import (
    floor_entities,
    obstacle_entity,
    stamp,
    transform,
    truck_entities,
)
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.settings import WorldParams


@settings_class
class LiveViewSettings:
    """The live view's parameters."""


def _tf_message_type() -> Any:
    """Return tf2_msgs/TFMessage where it can be imported (a ROS install), else None."""
    try:
        return importlib.import_module('tf2_msgs.msg').TFMessage
    except ImportError:
        return None


class TruckView:
    """One truck's subscriptions and channels (its namespace `ns`)."""

    def __init__(self, view: LiveView, ns: str, shape: TruckShape, track: float) -> None:
        self.view, self.ns, self.shape = view, ns.strip('/'), shape
        self.prefix = f'/{self.ns}' if self.ns else ''
        self.frames = TruckFrames(ns, shape, track)
        self.records = 0
        node = view.node
        self.odom_pub = node.create_publisher(Odometry, f'{self.prefix}/odom', qos.EVENTS)
        self.truth_pub = node.create_publisher(Odometry, f'{self.prefix}/world/odom', qos.EVENTS)
        self.reports = LogChannel(f'{self.prefix}/reports')
        self.images = {name: RawImageChannel(f'{self.prefix}/hw/camera/{name}')
                       for name in ('front', 'rear')}
        self.channels: dict[str, tuple[RecordReader, foxglove.Channel]] = {}
        for schema in codec():
            reader = RecordReader(schema, 'e2e' if schema.protected else 'none')
            channel = foxglove.Channel(decoded_topic(schema, self.ns), schema=json_schema(schema),
                                       message_encoding='json')
            self.channels[schema.name] = (reader, channel)
            node.create_subscription(
                UInt8MultiArray, f'{self.prefix}/{schema.topic.lstrip("/")}',
                partial(self.on_record, schema.name),
                qos.reader_qos(schema), raw=True)
        node.create_subscription(PoseStamped, f'{self.prefix}/world/pose', self.on_pose,
                                 qos.STREAM_READER)
        node.create_subscription(String, f'{self.prefix}/comms/report',
                                 self.on_report, qos.EVENTS)
        for name in self.images:
            node.create_subscription(Image, f'{self.prefix}/hw/camera/{name}',
                                     partial(self.on_image, name),
                                     qos.STREAM_READER)

    def now(self) -> float:
        """Return the graph's time (sim time under /clock), s."""
        return self.view.node.get_clock().now().nanoseconds * 1e-9

    def log(self, level: LogLevel, name: str, text: str) -> None:
        """Send one log line to the viewer."""
        t = self.now()
        self.reports.log(Log(timestamp=stamp(t), level=level, message=text, name=name),
                         log_time=round(t * 1e9))

    def on_record(self, name: str, raw: bytes) -> None:
        """Decode one record for the viewer; wheel odometry also moves `odom`."""
        reader, channel = self.channels[name]
        t = self.now()
        message = decoded(reader, record_bytes(raw), round(t * 1e9))
        channel.log(message, log_time=round(t * 1e9))
        self.records += 1
        if name == 'wheel_odometry' and message['verdict'] == 'accepted':
            self.on_wheels(message, t)
        elif name == 'world_event' and message['verdict'] == 'accepted':
            self.log(LogLevel.Info, 'world/events', ' '.join(
                f'{k}={v}' for k, v in message.items() if k not in ('raw', 'verdict')))

    def on_wheels(self, fields: dict[str, Any], t: float) -> None:
        """Dead-reckon and publish `odom` and the frames."""
        p = self.frames.on_wheels(fields)
        if p is None:
            return  # odom is tied to map where the world says the truck stands
        self.odom_pub.publish(odometry_message(p, t, self.frames.name('odom'),
                                               self.frames.name('base_link')))
        self.view.send_transforms([transform(t, *f) for f in
                                   self.frames.moving() + self.frames.fixed()], t)

    def on_report(self, msg: String) -> None:
        """Log a comms/report line."""
        self.log(LogLevel.Info, 'comms/report', msg.data)

    def on_pose(self, msg: PoseStamped) -> None:
        """Take the world's ground truth; publish it as Odometry in `map`."""
        q = msg.pose.orientation
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        before, before_t = self.frames.truth, self._truth_t
        truth = self.frames.on_truth(msg.pose.position.x, msg.pose.position.y,
                                     2.0 * math.atan2(q.z, q.w))
        if before is not None and t > before_t:
            truth.speed = math.hypot(truth.x - before.x, truth.y - before.y) / (t - before_t)
        self._truth_t = t
        self.truth_pub.publish(odometry_message(truth, t, 'map', self.frames.name('base_link')))

    _truth_t = 0.0

    def on_image(self, name: str, msg: Image) -> None:
        """Forward a camera frame."""
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.images[name].log(RawImage(
            timestamp=stamp(t), frame_id=frame(self.ns, f'camera_{name}'), width=msg.width,
            height=msg.height, encoding=msg.encoding, step=msg.step, data=bytes(msg.data)),
            log_time=round(t * 1e9))


def odometry_message(p: PlanarPose, t: float, parent: str, child: str) -> Odometry:
    """Return nav_msgs/Odometry of pose `p` in `parent` (twist in `child`)."""
    msg = Odometry()
    sec = math.floor(t)
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, min(round((t - sec) * 1e9),
                                                              999_999_999)
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.pose.pose.position.x, msg.pose.pose.position.y = p.x, p.y
    msg.pose.pose.orientation.z = math.sin(p.heading / 2.0)
    msg.pose.pose.orientation.w = math.cos(p.heading / 2.0)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = p.speed, p.yaw_rate
    return msg


class LiveView:
    """The node, the Foxglove server and one TruckView per truck."""

    def __init__(self, node: Node) -> None:
        self.node = node
        s = declare(node, LiveViewSettings)
        refuse_unknown(node)
        try:
            self.layout = load_layout(layout_path(s.layout))
        except (LayoutError, OSError) as exc:
            raise parameter_error(node, 'layout', s.layout, str(exc)) from None
        world = WorldParams()
        shape = truck_shape(self.layout.vehicle, self.layout.sensor_lateral, world)
        track = s.track or track_of(shape, world)
        self.server = foxglove.start_server(name='agv_nodes', host=s.host, port=s.port)
        print(f'live_view: Foxglove WebSocket on ws://{s.host}:{self.server.port} '
              f'(open it in Foxglove: Open connection, Foxglove WebSocket)', flush=True)
        self.scene = SceneUpdateChannel('/scene')
        self.tf = FrameTransformsChannel('/tf')
        tf_type = _tf_message_type()
        self.ros_tf = node.create_publisher(tf_type, '/tf', qos.EVENTS) if tf_type else None
        self.trucks = [TruckView(self, ns, shape, track) for ns in s.trucks]
        self._floor = floor_entities(self.layout)
        self._obstacles: list[Marker] = []
        self._gone: list[str] = []  # obstacles removed since the last scene: deleted in it
        node.create_subscription(MarkerArray, 'world/obstacle_markers', self.on_obstacles,
                                 qos.LATCHED)
        node.create_timer(s.scene_period, self.send_scene)
        self.send_scene()

    def on_obstacles(self, msg: MarkerArray) -> None:
        """Take the world's obstacles standing now (the whole set, on every change)."""
        posts = [m for m in msg.markers if m.action == Marker.ADD and m.type == Marker.CYLINDER]
        now = {m.text for m in posts}
        self._gone += [m.text for m in self._obstacles if m.text not in now]
        self._obstacles = posts
        self.send_scene()

    def send_scene(self) -> None:
        """Send the floor and the trucks (for viewers that joined since)."""
        t = self.trucks[0].now() if self.trucks else 0.0
        entities = list(self._floor)
        entities += [obstacle_entity(m.text, m.pose.position.x, m.pose.position.y, m.scale.x,
                                     m.scale.z, t) for m in self._obstacles]
        for truck in self.trucks:
            entities += truck_entities(truck.shape, truck.ns, t)
        deletions = [SceneEntityDeletion(timestamp=stamp(t), id=f'obstacle/{name}',
                                         type=SceneEntityDeletionType.MatchingId)
                     for name in self._gone]
        self._gone = []
        self.scene.log(SceneUpdate(deletions=deletions, entities=entities),
                       log_time=round(t * 1e9))

    def send_transforms(self, transforms: list, t: float) -> None:
        """Send frames to the viewer, and to ROS's /tf where tf2_msgs exists."""
        self.tf.log(FrameTransforms(transforms=transforms), log_time=round(t * 1e9))
        if self.ros_tf is not None:
            self.ros_tf.publish(ros_tf_message(self.ros_tf.msg_type, transforms))

    def close(self) -> None:
        """Stop the server."""
        self.server.stop()


def ros_tf_message(tf_type: Any, transforms: list) -> Any:
    """Return a tf2_msgs/TFMessage of Foxglove FrameTransforms (a ROS install only)."""
    from geometry_msgs.msg import TransformStamped

    out = tf_type()
    for f in transforms:
        ts = TransformStamped()
        ts.header.stamp.sec, ts.header.stamp.nanosec = f.timestamp.sec, f.timestamp.nsec
        ts.header.frame_id, ts.child_frame_id = f.parent_frame_id, f.child_frame_id
        ts.transform.translation.x = f.translation.x
        ts.transform.translation.y = f.translation.y
        ts.transform.rotation.z, ts.transform.rotation.w = f.rotation.z, f.rotation.w
        out.transforms.append(ts)
    return out


class LiveViewNode(Node):
    """The live view as a node (ros2 run agv_nodes live_view)."""

    def __init__(self) -> None:
        super().__init__('live_view')
        self.view = LiveView(self)

    def destroy_node(self) -> None:
        """Stop the server with the node."""
        self.view.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes live_view [--ros-args -p port:=8765 -p layout:=NAME]."""
    return spin_main(LiveViewNode, args)


if __name__ == '__main__':
    sys.exit(main())

