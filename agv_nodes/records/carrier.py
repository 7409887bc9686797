"""The carriers of the records on the wire, in their serialized CDR form (ROS-free).

Records travel as std_msgs/UInt8MultiArray with an empty layout, the clock as rosgraph_msgs/Clock;
nodes and report take both serialized (`raw=True`): rclpy 7.1.6 spends more making a Python message
than taking it (a 340 Hz reader took 7.7-9.1 % of a core, raw 4.3-4.9 %, bench/rclpy_bench.py
--message record; rosbags' deserializer took 6.8 of a report's 18.6 s). Only the shapes this
package sends (CDR little endian, every DDS's default on x86 and ARM) are read; anything else is
None, for the caller's general deserializer.
"""

import struct

CDR_LE = b'\x00\x01\x00\x00'  # encapsulation: plain CDR, little endian, no options
_EMPTY_LAYOUT_LE = CDR_LE + bytes(8)  # layout.dim = [] (u32 0), layout.data_offset = 0 (u32)
_CLOCK = struct.Struct('<iI')  # builtin_interfaces/Time: int32 sec, uint32 nanosec


def uint8_array_data(raw: bytes | memoryview) -> bytes | None:
    """Return the `data` of a serialized std_msgs/UInt8MultiArray, empty layout; else None."""
    if len(raw) < 16 or bytes(raw[:12]) != _EMPTY_LAYOUT_LE:
        return None
    n = int.from_bytes(raw[12:16], 'little')
    return bytes(raw[16:16 + n]) if len(raw) >= 16 + n else None


def uint8_array_cdr(data: bytes) -> bytes:
    """Serialize `data` as UInt8MultiArray(data=data) with an empty layout, as rclpy would."""
    return _EMPTY_LAYOUT_LE + len(data).to_bytes(4, 'little') + data


def clock_ns(raw: bytes | memoryview) -> int | None:
    """Return the time of a serialized rosgraph_msgs/Clock in ns; None for any other shape."""
    if len(raw) < 12 or bytes(raw[:4]) != CDR_LE:
        return None
    sec, nanosec = _CLOCK.unpack_from(raw, 4)
    return sec * 1_000_000_000 + nanosec


def clock_cdr(ns: int) -> bytes:
    """Serialize a rosgraph_msgs/Clock at `ns` (as rclpy's serializer writes it)."""
    sec, nanosec = divmod(ns, 1_000_000_000)
    return CDR_LE + _CLOCK.pack(sec, nanosec)
