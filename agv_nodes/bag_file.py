"""The recorder's bag file: MCAP commits that survive a kill, and QoS profiles as metadata.

The recorder (agv_nodes/recorder.py) writes through rosbags' Writer; CommittedFile stands in
for the MCAP file under it, and to_bag_qos turns a publisher's offered rclpy QoS profile into
the offered_qos_profiles of the bag's metadata.yaml.
"""

from __future__ import annotations

import errno
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

    A write the disk has no room for (or beyond `space_limit`, which meets it as the same
    OSError ENOSPC) fails its commit: the file is put back as the last commit left it, so the
    bag still reads to its last committed chunk, and the caller stops writing
    (agv_nodes/recorder.py).
    """

    def __init__(self, raw: Any, space_limit: int = 0) -> None:
        self.space_limit = space_limit  # bytes the file may reach (0: what the disk has)
        self._raw = raw
        self._fd = raw.fileno()
        self._tail = b''  # the summary and footer of the last commit, which end the file
        self._pending = bytearray()
        self._data: int | None = None  # at a checkpoint: pending bytes that are data
        raw.flush()
        self._done = raw.tell()  # bytes committed for good (the header rosbags wrote at open)
        if space_limit and self._done > space_limit:
            raise OSError(errno.ENOSPC, f'{os.strerror(errno.ENOSPC)} (space_limit '
                                        f'{space_limit} bytes)')

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

    def _put(self, data: memoryview, offset: int, limited: bool = True) -> None:
        """Write `data` at `offset`, as far as the space allows (OSError ENOSPC beyond it)."""
        limit = self.space_limit if limited else 0
        if limit and offset + len(data) > limit:
            # a full disk, as a write meets one: what fits is written, then ENOSPC
            self._put(data[:max(0, limit - offset)], offset, limited=False)
            raise OSError(errno.ENOSPC, f'{os.strerror(errno.ENOSPC)} (space_limit {limit} '
                                        'bytes)')
        while data:
            n = os.pwrite(self._fd, data, offset)
            data, offset = data[n:], offset + n

    def close(self) -> None:
        """Commit (rosbags' close). After mark(): keep the file open for more.

        A commit that fails (a full disk: OSError) puts the last commit's summary and footer
        back after its data, so the file is again the bag as committed last, and raises.
        """
        end = self.tell()
        try:
            self._put(memoryview(bytes(self._pending)), self._done)
        except OSError:
            self._restore()
            raise
        if os.fstat(self._fd).st_size > end:
            os.ftruncate(self._fd, end)  # a shorter summary than the last one
        if self._data is None:
            self._raw.close()
            return
        self._tail = bytes(self._pending[self._data:])
        self._done += self._data
        self._pending.clear()
        self._data = None

    def _restore(self) -> None:
        """Make the file the last commit again: its data, then its summary and footer."""
        os.ftruncate(self._fd, self._done)  # frees what the failed write took
        # where it was before the failed write: it fits, whatever the limit is now
        self._put(memoryview(self._tail), self._done, limited=False)

    def abandon(self) -> None:
        """Close the file as committed last; what is pending is dropped."""
        self._pending.clear()
        self._raw.close()


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
