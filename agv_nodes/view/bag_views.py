"""What a bag adds for a person to read: decoded records beside it, the trucks' frames in it.

The recorder (agv_nodes/recorder.py) hands each message it writes to `BagViews.take`:

- a record (a 16-byte topic of msg_schemas/, in any truck's namespace) is decoded as the live
  view decodes it (agv_nodes.records.decoded: the fields by name, the reader's verdict, the E2E
  counter) and written as JSON, with the record's JSON schema, to `decoded.mcap` in the bag's
  directory, on `[/<ns>]/decoded/<record topic>` at the same time stamp. rosbag2's MCAP files
  carry CDR only, so the JSON channels live in a file of their own, which Foxglove and
  PlotJuggler open beside the bag's (and `mcap` reads);
- the world's pose and the wheel odometry move each truck's frames (agv_nodes.view.frames), and
  `take` returns `/tf` (tf2_msgs/msg/TFMessage) messages for the bag itself, and one
  `/tf_static` of the sensors' frames per truck: rosbags knows the type, so the frames are in
  every bag, where tf2_msgs cannot be imported as well as where it can.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from mcap.writer import Writer as McapWriter
from rosbags.typesys import Stores, get_typestore

from agv_nodes.records import codec
from agv_nodes.records.carrier import uint8_array_data
from agv_nodes.records.decoded import decoded, decoded_topic, json_schema
from agv_nodes.records.ports import RecordReader
from agv_nodes.records.schema import RecordSchema
from agv_nodes.view.frames import Transform, TruckFrames, TruckShape

DECODED_FILE = 'decoded.mcap'
TF_TYPE, POSE_TYPE = 'tf2_msgs/msg/TFMessage', 'geometry_msgs/msg/PoseStamped'


class BagViews:
    """Decoded records into `<bag>/decoded.mcap`; the frames returned for the bag."""

    def __init__(self, bag_dir: Path, shape: TruckShape, track: float,
                 integrity: str = 'e2e') -> None:
        self.path = bag_dir / DECODED_FILE
        self._file = self.path.open('wb')
        self._mcap = McapWriter(self._file)
        self._mcap.start(profile='', library='agv_nodes recorder')
        self.shape, self.track, self.integrity = shape, track, integrity
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self._records = {f'/{s.topic.lstrip("/")}': s for s in codec()}
        self._channels: dict[str, tuple[int, RecordReader]] = {}  # topic -> channel, reader
        self._schemas: dict[str, int] = {}
        self._trucks: dict[str, TruckFrames] = {}
        self.written = 0

    def record_of(self, topic: str) -> tuple[str, RecordSchema] | None:
        """Return (namespace, schema) of a record topic, or None for any other topic."""
        for suffix, schema in self._records.items():
            if topic.endswith(suffix):
                ns = topic[:-len(suffix)].strip('/')
                return ns, schema
        return None

    def take(self, topic: str, raw: bytes, stamp_ns: int) -> list[tuple[str, str, bytes]]:
        """Take one message the bag gets; return (topic, type, CDR) messages to add to it."""
        if topic.endswith('/world/pose'):
            return self._pose(topic[:-len('/world/pose')].strip('/'), raw, stamp_ns)
        found = self.record_of(topic)
        if found is None:
            return []
        ns, schema = found
        data = uint8_array_data(raw)
        if data is None:
            return []  # a layout of a driver's own: the bag has it raw
        message = decoded(self._reader(ns, schema), data, stamp_ns)
        channel = self._channels[f'{ns}/{schema.name}'][0]
        self._mcap.add_message(channel, log_time=stamp_ns, publish_time=stamp_ns,
                               data=json.dumps(message).encode())
        self.written += 1
        if schema.name == 'wheel_odometry' and message['verdict'] == 'accepted':
            return self._wheels(ns, message, stamp_ns)
        return []

    def close(self) -> None:
        """Finish decoded.mcap (its index and footer)."""
        if self._file.closed:
            return
        self._mcap.finish()
        self._file.close()

    # -- decoded records ---------------------------------------------------------------------
    def _reader(self, ns: str, schema: RecordSchema) -> RecordReader:
        key = f'{ns}/{schema.name}'
        if key not in self._channels:
            if schema.name not in self._schemas:
                self._schemas[schema.name] = self._mcap.register_schema(
                    name=f'agv_nodes.{schema.name}', encoding='jsonschema',
                    data=json.dumps(json_schema(schema)).encode())
            channel = self._mcap.register_channel(
                topic=decoded_topic(schema, ns), message_encoding='json',
                schema_id=self._schemas[schema.name])
            integrity = self.integrity if schema.protected else 'none'
            self._channels[key] = (channel, RecordReader(schema, integrity))
        return self._channels[key][1]

    # -- frames ---------------------------------------------------------------------------
    def _truck(self, ns: str) -> tuple[TruckFrames, list[tuple[str, str, bytes]]]:
        """Return the truck's frames, and its /tf_static if it is new."""
        if ns in self._trucks:
            return self._trucks[ns], []
        frames = self._trucks[ns] = TruckFrames(ns, self.shape, self.track)
        return frames, [('/tf_static', TF_TYPE, self._tf(frames.fixed(), 0))]

    def _pose(self, ns: str, raw: bytes, stamp_ns: int) -> list[tuple[str, str, bytes]]:
        frames, out = self._truck(ns)
        msg: Any = self.typestore.deserialize_cdr(raw, POSE_TYPE)  # rosbags: `object`
        q = msg.pose.orientation
        frames.on_truth(msg.pose.position.x, msg.pose.position.y, 2.0 * math.atan2(q.z, q.w))
        return out

    def _wheels(self, ns: str, fields: dict[str, Any],
                stamp_ns: int) -> list[tuple[str, str, bytes]]:
        frames, out = self._truck(ns)
        if frames.on_wheels(fields) is None:
            return out
        return out + [('/tf', TF_TYPE, self._tf(frames.moving(), stamp_ns))]

    def _tf(self, transforms: list[Transform], stamp_ns: int) -> bytes:
        ts = self.typestore
        Time = ts.types['builtin_interfaces/msg/Time']
        Header = ts.types['std_msgs/msg/Header']
        Stamped = ts.types['geometry_msgs/msg/TransformStamped']
        Tf = ts.types['geometry_msgs/msg/Transform']
        Vector3 = ts.types['geometry_msgs/msg/Vector3']
        Quaternion = ts.types['geometry_msgs/msg/Quaternion']
        stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        msg = ts.types[TF_TYPE](transforms=[
            Stamped(header=Header(stamp=stamp, frame_id=parent), child_frame_id=child,
                    transform=Tf(translation=Vector3(x=x, y=y, z=0.0),
                                 rotation=Quaternion(x=0.0, y=0.0, z=math.sin(h / 2.0),
                                                     w=math.cos(h / 2.0))))
            for parent, child, x, y, h in transforms])
        return bytes(ts.serialize_cdr(msg, TF_TYPE))
