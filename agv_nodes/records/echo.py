"""agv-records echo: print a live record topic field by field, with each record's E2E verdict.

What `ros2 topic echo` shows of a record topic is sixteen numbers, counter and CRC included;
this reads the same messages and prints each as its fields (YAML, one document a record, as
`ros2 topic echo` separates them) with what the values mean and the verdict a node's reader
would reach on it: accepted, or rejected and why (bad CRC, a repeated counter, ...). The
verdict is the reader's own (agv_nodes.records.ports.RecordReader): a record this prints as
rejected is one the nodes count and never act on. Every writer's records are shown (a reader
in a node hears only its named writer); the writer's GID is printed where it can be had.

`describe_record` is the ROS-free part the tests hold; `echo` subscribes with rclpy.
"""

from __future__ import annotations

from collections.abc import Callable
import time
from typing import Any

import yaml

from agv_nodes.records.codec import Codec
from agv_nodes.records.decoded import decoded
from agv_nodes.records.ports import RecordReader
from agv_nodes.records.schema import RecordSchema


def find_schema(codec: Codec, name: str) -> RecordSchema:
    """Return the record named `name`, or the one whose topic it is (with or without its '/')."""
    topic = name.lstrip('/')
    for schema in codec:
        if name == schema.name or topic == schema.topic.lstrip('/'):
            return schema
    raise KeyError(f'{name!r}: no record or record topic of that name (agv-records list)')


def describe_record(reader: RecordReader, raw: bytes, now_ns: int,
                    writer: str = '') -> str:
    """Return one record as `agv-records echo` prints it (a YAML document, '---' after it).

    The reader judges it as a node's reader would, so its sequence rules see the records
    before it.
    """
    schema = reader.schema
    message = decoded(reader, raw, now_ns)
    lines = [f'record: {schema.name}  # {schema.topic}, {len(raw)} bytes: {raw.hex(" ")}']
    if writer:
        lines.append(f'writer: {writer}')
    if message['verdict'] == 'accepted':
        lines.append('verdict: accepted')
    else:
        lines.append(f'verdict: rejected {reader.last_reason}  # {reader.last_error}')
    if 'e2e_counter' in message:
        lines.append(f'e2e_counter: {message["e2e_counter"]}')
    fields = {f.name: message[f.name] for f in schema.fields if f.name in message}
    if fields:
        meaning = schema.describe(fields)
        for name, value in fields.items():
            shown = yaml.safe_dump({name: value}, default_flow_style=True).strip()[1:-1]
            lines.append(f'{shown:32s} # {meaning[name]}')
    return '\n'.join(lines) + '\n---'


def echo(schema: RecordSchema, integrity: str, count: int, timeout: float,
         out: Callable[[str], None] = print) -> int:
    """Print records of `schema`'s topic as they come; return how many were printed.

    Stops after `count` records (0: never) or `timeout` s of wall time without one (0: never).
    """
    import rclpy
    from rclpy.node import Node
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos
    from agv_nodes.rclpy_internals import writer_tagged_subscription
    from agv_nodes.ros_ports import record_bytes

    reader = RecordReader(schema, integrity if schema.protected else 'none')
    printed = 0
    last = time.monotonic()

    def take(raw: bytes, gid: bytes | None = None, _stamp: int = 0) -> None:
        nonlocal printed, last
        if count and printed >= count:
            return
        data = record_bytes(raw)
        out(describe_record(reader, data, time.monotonic_ns(), gid.hex() if gid else ''))
        printed += 1
        last = time.monotonic()

    rclpy.init()
    node = Node('agv_records_echo')
    tagged = writer_tagged_subscription(node, UInt8MultiArray, schema.topic,
                                        qos.reader_qos(schema), take)
    if tagged is None:
        node.create_subscription(UInt8MultiArray, schema.topic, take, qos.reader_qos(schema),
                                 raw=True)
    try:
        while rclpy.ok() and (not count or printed < count):
            rclpy.spin_once(node, timeout_sec=0.1)
            if timeout and time.monotonic() - last > timeout:
                break
    except KeyboardInterrupt:
        pass
    finally:
        if tagged is not None:
            tagged.destroy()
        node.destroy_node()
        rclpy.try_shutdown()
    return printed


def run(codec: Codec, name: str, integrity: str, count: int, timeout: float) -> int:
    """Entry of `agv-records echo`: exit status 0, or 1 when no record came before the timeout."""
    schema = find_schema(codec, name)
    printed = echo(schema, integrity, count, timeout)
    return 0 if printed or not timeout else 1


def _fields_of(text: str) -> dict[str, Any]:
    """Return the field lines of one printed record as a dict (tests and scripts)."""
    doc = yaml.safe_load(text.split('\n---')[0])
    return {k: v for k, v in doc.items()
            if k not in ('record', 'writer', 'verdict', 'e2e_counter')}
