"""The one place for QoS profiles.

A record topic is a pigeon-hole (Baker 1983, 8.2.2): the writer offers reliable + transient-
local keep-last 1 and republishes at a steady rate, so a late joiner gets the current record at
once and a silent writer is noticed by age. Readers ask for the weakest QoS that does the job
(reliable + volatile for records; best-effort for the 340 Hz ADC stream and camera frames), because
a best-effort writer never matches a reliable reader and a volatile writer never matches a
transient-local reader. Record readers keep 50 records so that every record is seen and judged even
when a foreign writer floods the topic while the node is busy (the fuzz test counts every
rejection; with 10 a few were dropped unseen). Stream readers keep 0.3 s of the 340 Hz ADC stream
(100 samples): a Python node on a loaded two-core machine can stall for tens of milliseconds, and a
best-effort reader with a 10-deep queue (29 ms) then drops samples, breaking the run-length
patterns a marker passage is recognised by (a location marker was missed this way in a full-
programme run on a saturated machine); the 1983 sensor never lost a sample, so neither should we.
Stream writers keep 100 samples too: to a reliable reader (the recorder, a node's FIFO /clock)
a sample is lost only when it has left the writer's history before the reader acknowledged it,
and with 10 that was 11 ms of wall time with the graph at 2.7x real time (the quick demo's bag
held 323 of 340 snapshots per second on a loaded machine).
"""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from agv_nodes.records.schema import RecordSchema


def _keep_last(depth: int, *, reliable: bool = True, latched: bool = False) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


RECORD_WRITER = _keep_last(1, latched=True)
RECORD_READER = _keep_last(50)
STREAM_WRITER = _keep_last(100)
STREAM_READER = _keep_last(100, reliable=False)
# A node's own FIFO /clock reader (core_node.ClockTimers, the executive's sent timeline): every
# sample, in order - a lost one would leave the node's time and timers behind until the next.
CLOCK_READER = _keep_last(100)
# Ground truth drawn once (world/route, world/markers) and late-joining viewers or recorders.
LATCHED = _keep_last(1, latched=True)
# graph/links (ros_ports.LinkAnnouncer): each node's latched word; the world keeps them all.
LINKS_READER = _keep_last(100, latched=True)
# sim/progress/<node> (agv_nodes/sim_progress.py): each node's latest handled sim time; only
# the newest counts, and the world must see it, so reliable with a short history.
PROGRESS = _keep_last(5)
# /diagnostics, reports, ground-truth streams: reliable, volatile.
EVENTS = _keep_last(50)


def writer_qos(schema: RecordSchema) -> QoSProfile:
    """QoS a writer of `schema`'s topic offers."""
    return RECORD_WRITER if schema.qos == 'record' else STREAM_WRITER


def reader_qos(schema: RecordSchema) -> QoSProfile:
    """QoS a reader of `schema`'s topic requests."""
    return RECORD_READER if schema.qos == 'record' else STREAM_READER
