"""A small rclpy peer for DDS tests.

`pub RECORD k=v ...` publishes a record steadily; `echo RECORD N` prints the first N records
accepted on its topic as JSON lines, then exits.
"""

from __future__ import annotations

import json
import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node

from agv_nodes.records import codec
from agv_nodes.records.cli import _parse_value
from agv_nodes.ros_ports import RecordPublisher, RecordSubscription

RCLError = rclpy_implementation.RCLError


def main() -> int:
    mode, record, *rest = sys.argv[1:]
    rclpy.init()
    node = Node(f'dds_peer_{mode}')
    schema = codec()[record]
    try:
        if mode == 'pub':
            fields = {k: _parse_value(v) for k, v in (a.split('=', 1) for a in rest)}
            pub = RecordPublisher(node, schema)

            def publish() -> None:
                try:
                    pub.publish(fields)
                except RCLError:  # SIGINT shut the context down while the timer ran: done
                    if rclpy.ok():
                        raise
            node.create_timer(schema.period_ms / 1000.0, publish)
            rclpy.spin(node)
        else:
            wanted = int(rest[0])
            got: list[dict] = []

            def on_record(fields: dict) -> None:
                if len(got) < wanted:  # records held for the graph to name the writer come at once
                    got.append(fields)
                    print(json.dumps({'fields': fields, 'raw': sub.raw.hex()}), flush=True)

            # the other peer stands in for the schema's writer
            sub = RecordSubscription(node, schema, callback=on_record, writer='/dds_peer_pub')
            while rclpy.ok() and len(got) < wanted:
                rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
