"""The one place for QoS profiles (the rule and the table: docs/architecture.md, "QoS").

Record readers keep 50 so that every record is seen and judged even when a foreign writer floods
the topic while the node is busy (with 10 the fuzz test saw a few dropped unseen). Stream readers
keep 100 (0.3 s of the 340 Hz ADC): a Python node on a loaded two-core machine stalls for tens of
ms, and a 10-deep best-effort queue (29 ms) then drops samples, breaking the run-length patterns a
marker passage is recognised by (a location marker was missed so); the 1983 sensor never lost a
sample. Stream writers keep 100 too: a reliable reader (the recorder, a FIFO /clock) loses a sample
that leaves the writer's history before it acknowledged it: with 10 the quick demo's bag held
323 of 340 snapshots a second on a loaded machine, and with 100 (0.1 s of wall time at the demo's
3x) 330 of 340 on a slower one. A writer keeps 1000 (about 1 s of wall time at 3x): 16-byte
records, so 16 kB a topic.
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from agv_nodes.records.schema import RecordSchema


def _keep_last(depth: int, *, reliable: bool = True, latched: bool = False) -> QoSProfile:
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                      else DurabilityPolicy.VOLATILE)


RECORD_WRITER = _keep_last(1, latched=True)
RECORD_READER = _keep_last(50)
STREAM_WRITER = _keep_last(1000)
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
# comms/task's reader and comms/report's writer: more of a burst of tasks reaches communications,
# each queued or refused with its own line (of a burst of 400, 347 never arrived with 50, 124-135
# with 256: test_task_flood_dds.py); what is lost is counted (docs/tasks.md, "Limits").
TASKS = _keep_last(256)


def writer_qos(schema: RecordSchema) -> QoSProfile:
    """QoS a writer of `schema`'s topic offers."""
    return RECORD_WRITER if schema.qos == 'record' else STREAM_WRITER


def reader_qos(schema: RecordSchema) -> QoSProfile:
    """QoS a reader of `schema`'s topic requests."""
    return RECORD_READER if schema.qos == 'record' else STREAM_READER
