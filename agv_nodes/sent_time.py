"""SentTimeline: the sim time a record was sent at, from its DDS source timestamp (ROS-free).

A status record's age decides whether a sub-system is alive (thesis 6.3: the monostables). The 1983
bus measured it on arrival; a simulated graph must not: a starved reader's `/clock` reader keeps
only the latest message and jumps ahead at once while the records sent meanwhile wait in their
queues, so every record looks old when it wakes (the executive saw statuses up to 0.16 s old with
every writer paced within 0.07 s: a false `stale status` about one run in three, bench/results).

What matters is how long ago, in sim time, the writer *sent* it. DDS stamps every sample with the
writer's wall clock (one host, one clock); the reader keeps the world's `/clock` samples in order
(a FIFO reader, so its time advances no faster than it takes its inputs) with their source
timestamps, and `sim_at(sent)` is the sim time the world had reached at the send. After a stall the
status queues (20-60 Hz) empty before the clock queue (113 Hz): a record taken before the clock
samples bracketing its send gets the latest sim time known, raised as they come in. A queued record
is never blamed; a dead writer is aged exactly.
"""

from bisect import bisect_right
from collections import deque


class SentTimeline:
    """(source wall time, sim time) samples of the world's clock, oldest first, `keep` s of them.

    Before the oldest: its sim time less the wall time between (stale long before that matters).
    """

    def __init__(self, keep: float = 5.0) -> None:
        self.keep_ns = int(keep * 1e9)
        self._wall: deque[int] = deque()
        self._sim: deque[float] = deque()
        self._unplaced: dict[str, int] = {}  # record -> send (wall ns) after the latest sample

    def __bool__(self) -> bool:
        return bool(self._wall)

    def clock(self, sent_ns: int, sim: float) -> list[tuple[str, float]]:
        """Take a /clock sample (source stamp ns, value s); return the (record, sim) it raises."""
        if self._wall and sim < self._sim[-1] - 1.0 and sent_ns > self._wall[-1]:
            self._wall.clear()  # sim time went back: a new (respawned) world, a new timeline
            self._sim.clear()
        elif self._wall and (sent_ns < self._wall[-1] or sim < self._sim[-1]):
            return []  # out of order (best-effort transport): the later sample already counts
        self._wall.append(sent_ns)
        self._sim.append(sim)
        while self._wall[-1] - self._wall[0] > self.keep_ns:
            self._wall.popleft()
            self._sim.popleft()
        raised = []
        for name, record_ns in list(self._unplaced.items()):
            if sent_ns <= record_ns:  # sent after this sample too
                raised.append((name, sim))
            else:  # the first sample after its send: the time given last is final
                del self._unplaced[name]
        return raised

    def record(self, name: str, sent_ns: int) -> float:
        """Sim time a record taken now was sent at; one sent after the latest sample is kept."""
        if sent_ns >= self.latest_ns():
            self._unplaced[name] = sent_ns
        else:
            self._unplaced.pop(name, None)
        return self.sim_at(sent_ns)

    def latest_ns(self) -> int:
        """Source timestamp of the latest clock sample taken (0 before the first)."""
        return self._wall[-1] if self._wall else 0

    def now(self) -> float:
        """Sim time of the latest clock sample taken (0 before the first)."""
        return self._sim[-1] if self._sim else 0.0

    def sim_at(self, sent_ns: int) -> float:
        """Sim time at this source timestamp (after the latest sample, a lower bound: `record`)."""
        if not self._wall:
            return 0.0
        i = bisect_right(self._wall, sent_ns)
        if i == 0:
            return self._sim[0] - (self._wall[0] - sent_ns) * 1e-9
        return self._sim[i - 1]
