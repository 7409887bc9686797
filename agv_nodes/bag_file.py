"""The recorder's bag file: MCAP commits that survive a kill, and QoS profiles as metadata.

The recorder (agv_nodes/recorder.py) writes through rosbags' Writer; CommittedFile stands in
for the MCAP file under it, and to_bag_qos turns a publisher's offered rclpy QoS profile into
the offered_qos_profiles of the bag's metadata.yaml.
"""

from __future__ import annotations

import os
from typing import Any

from rclpy.qos import QoSProfile
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)


class CommittedFile:
    """The bag's MCAP file as rosbags' writer sees it, made to survive a kill at any moment.

    rosbags keeps the open chunk and the file's buffer in memory and writes the summary, the
    footer and metadata.yaml only when the bag is closed: a SIGKILLed recorder left an empty
    or footless MCAP file and no metadata.yaml, which no reader opens. Its writes come here,
    into memory. At a checkpoint (`mark()`, then rosbags' own close) what has been written is
    committed, with that close's summary and footer after it, in one write where the previous
    checkpoint's summary began; the next checkpoint writes over that summary. The file on disk
    is thus always whole chunks, their index and a footer: a bag indexed as far as the last
    checkpoint. The final close (no mark) writes the summary for good and trims the file.
    """

    def __init__(self, raw: Any) -> None:
        raw.flush()
        self._raw = raw
        self._fd = raw.fileno()
        self._done = raw.tell()  # bytes committed for good (the header rosbags wrote at open)
        self._pending = bytearray()
        self._data: int | None = None  # at a checkpoint: pending bytes that are data

    def write(self, data: Any) -> int:
        """Take bytes (rosbags' record writes); they reach the file at the next commit."""
        self._pending += data
        return len(data)

    def tell(self) -> int:
        """Return the file offset rosbags writes at (its chunk and summary offsets)."""
        return self._done + len(self._pending)

    @property
    def has_new_data(self) -> bool:
        """Return True if records were written since the last commit."""
        return bool(self._pending)

    def mark(self) -> None:
        """Checkpoint: what is pending is data; what rosbags writes until close() the summary."""
        self._data = len(self._pending)

    def _put(self, data: memoryview, offset: int) -> None:
        while data:
            n = os.pwrite(self._fd, data, offset)
            data, offset = data[n:], offset + n

    def close(self) -> None:
        """Commit (rosbags' close). After mark(): keep the file open for more."""
        end = self.tell()
        self._put(memoryview(bytes(self._pending)), self._done)
        if os.fstat(self._fd).st_size > end:
            os.ftruncate(self._fd, end)  # a shorter summary than the last one
        if self._data is None:
            self._raw.close()
            return
        self._done += self._data
        self._pending.clear()
        self._data = None


def _time(duration: Any) -> QosTime:
    ns = duration.nanoseconds if hasattr(duration, 'nanoseconds') else 0
    if ns >= 2**63 - 1 or ns < 0:  # "infinite"
        return QosTime(sec=2147483647, nsec=4294967295)
    return QosTime(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def to_bag_qos(profile: QoSProfile) -> Qos:
    """Return an rclpy QoS profile as rosbags metadata."""
    return Qos(history=QosHistory(int(profile.history)), depth=int(profile.depth),
               reliability=QosReliability(int(profile.reliability)),
               durability=QosDurability(int(profile.durability)),
               deadline=_time(profile.deadline), lifespan=_time(profile.lifespan),
               liveliness=QosLiveliness(int(profile.liveliness)),
               liveliness_lease_duration=_time(profile.liveliness_lease_duration),
               avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions))
