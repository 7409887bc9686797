"""A marker-sensor driver on plain DDS (Cyclone DDS, no rclpy): adc_snapshot on the ROS topic.

What a board driver written without ROS does: a Cyclone DDS participant on the graph's domain
writes `std_msgs::msg::dds_::UInt8MultiArray_` samples on `rt/hw/position_sensor/adc` (the ROS
topic's DDS name), each carrying one 16-byte adc_snapshot record made with the package's codec.
It has no ROS node: the graph shows its writer as `_CREATED_BY_BARE_DDS_APP_`. It prints its
writer's GUID (`gid <32 hex digits>`: the GID the ROS graph shows for the endpoint, and what a
reader's `record_writers` names it by), waits for a reader, then sends at 340 Hz until its stdin
closes and prints how many it sent. Discovery is localhost-only, as the package's Fast DDS
profile (agv_nodes/discovery.py): loopback unicast to the first 120 participant ports, no
multicast. Run: `python test/plain_dds_peer.py` with ROS_DOMAIN_ID set.
"""

# (no `from __future__ import annotations`: cyclonedds reads the field types as objects)
from dataclasses import dataclass
import os
import sys
import threading
import time

# Before cyclonedds is imported: it reads its configuration once.
os.environ.setdefault('CYCLONEDDS_URI', (
    '<CycloneDDS><Domain id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/>'
    '</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>'
    '<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>119'
    '</MaxAutoParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    '</Domain></CycloneDDS>'))

from cyclonedds.core import Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
import cyclonedds.idl.annotations as annotate  # noqa: E402
from cyclonedds.idl.types import sequence, uint8, uint32  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

RATE = 340.0  # Hz: the marker sensor's on/off samples (docs/hardware.md)


@dataclass
@annotate.final
class MultiArrayDimension(IdlStruct, typename='std_msgs::msg::dds_::MultiArrayDimension_'):
    """std_msgs/MultiArrayDimension as rosidl names it in DDS."""

    label: str
    size: uint32
    stride: uint32


@dataclass
@annotate.final
class MultiArrayLayout(IdlStruct, typename='std_msgs::msg::dds_::MultiArrayLayout_'):
    """std_msgs/MultiArrayLayout."""

    dim: sequence[MultiArrayDimension]
    data_offset: uint32


@dataclass
@annotate.final
class UInt8MultiArray(IdlStruct, typename='std_msgs::msg::dds_::UInt8MultiArray_'):
    """std_msgs/UInt8MultiArray: a record topic's message."""

    layout: MultiArrayLayout
    data: sequence[uint8]


def main() -> int:
    """Send adc_snapshot records until stdin closes."""
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..'))
    from agv_nodes.records import codec

    schema = codec()['adc_snapshot']
    participant = DomainParticipant(int(os.environ['ROS_DOMAIN_ID']))
    topic = Topic(participant, 'rt/' + schema.topic, UInt8MultiArray)
    # rmw_fastrtps reads and writes XCDR1; reliable, volatile, as the package's writers offer
    qos = Qos(Policy.Reliability.Reliable(max_blocking_time=duration(seconds=1)),
              Policy.History.KeepLast(400),
              Policy.DataRepresentation(use_cdrv0_representation=True))
    writer = DataWriter(participant, topic, qos)
    print(f'gid {writer.guid.bytes.hex()}', flush=True)
    deadline = time.monotonic() + 60
    while not writer.get_matched_subscriptions():
        if time.monotonic() > deadline:
            print('no reader matched in 60 s', flush=True)
            return 1
        time.sleep(0.05)
    print('matched', flush=True)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    sent, start = 0, time.monotonic()
    while not done.is_set():
        # the eight photodiodes lit and dark, as a floor with no marker under the sensor
        raw = schema.encode({**{f'lit_{k}': 40 + (sent + k) % 8 for k in range(1, 9)},
                             **{f'dark_{k}': 20 for k in range(1, 9)}}, integrity='none')
        writer.write(UInt8MultiArray(MultiArrayLayout([], 0), list(raw)))
        sent += 1
        time.sleep(max(0.0, start + sent / RATE - time.monotonic()))
    print(f'sent {sent}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
