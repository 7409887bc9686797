"""A live graph to fuzz: the probe as the records' named writer, and the exact counts due.

Only a topic's named writer reaches the codec and E2E checks; any other endpoint is rejected
as `foreign_writer` first. So the session's probe node stands in as the named writer
(`record_writers`) of every record a sub-system node reads, and the graph's own writers of
those records become foreign there. The world is no CoreNode and keeps its schema writers, so
on the three records it reads the probe is a foreign writer: those are the foreign part.
Used by test/test_bad_input_dds.py and bench/fuzz_bench.py; the defects are test/record_fuzz.py's,
and what each stand-in reader must do with each record is test/record_oracle.py's verdict (a
model written apart from the codec and the reader, from msg_schemas/ and docs/records.md).
"""

from __future__ import annotations

from collections import Counter
import math
import os
import time
from typing import Any

from record_fuzz import Recipe, apply
from record_oracle import ReaderOracle, Verdict, tables

from agv_nodes.records.schema import RecordSchema

STAND_IN = 'fuzz_writer'
GRAPH_NODES = ('position_sensor', 'navigation', 'traction', 'route_following', 'load_handling',
               'executive', 'communications', 'world')
FOREIGN_AT = frozenset({'world'})  # readers that keep their schema writers
PROBE = b'\x00\x01\x02'  # the hand-shake record: too short, so rejected by every reader


def fuzzed_schemas() -> list[RecordSchema]:
    """Every record topic a graph node reads (ground truth aside)."""
    from agv_nodes.records import codec

    return [s for s in codec() if s.kind != 'ground_truth'
            and any(r in GRAPH_NODES for r in s.readers)]


def stand_in_parameters(stand_in: str = STAND_IN) -> dict[str, list[str]]:
    """Return the `-p` arguments that make each sub-system node read from `stand_in`."""
    out = {}
    for node in GRAPH_NODES:
        reads = [s.name for s in fuzzed_schemas() if node in s.readers]
        if node not in FOREIGN_AT and reads:
            out[node] = ['record_writers:=[' + ', '.join(f"'{r}={stand_in}'" for r in reads)
                         + ']']
    return out


def reasons_of(values: dict[str, str], record: str) -> Counter[str]:
    """Rejections by reason of `record` in one /diagnostics inputs row's values."""
    text = values.get(f'{record} rejects by reason', 'none')
    if text == 'none':
        return Counter()
    return Counter({k: int(v) for k, v in (item.split('=') for item in text.split(', '))})


class FuzzSession:
    """Sends fuzzed records through a live graph as its stand-in writer; keeps what is due.

    Each stand-in reader's verdict comes from the oracle (test/record_oracle.py, which knows
    nothing of the code under test): one `ReaderOracle` per record sees the same records in the
    same order as every stand-in reader of it (the reference record, then every fuzzed one),
    and each codec recipe's reason is checked against the defect it made. Every record drawn
    is sent, and counted as the oracle says: rejected by reason, or accepted (a skipped counter
    that completes a resynchronisation run three long is a writer by the rules, so it is
    taken, and the sequence recipes go on from it). An accepted record carries the content of
    the last record taken, so taking it changes nothing the node acts on. The graph's own
    writers of these records are foreign at the stand-in readers, so `foreign_writer` there is
    theirs, not ours, and is left out of the exact comparison (it must merely be there).
    """

    def __init__(self, node: Any, executor: Any, integrity: str = 'e2e') -> None:
        from agv_nodes import qos
        from agv_nodes.ros_ports import RecordSubscription, full_name

        self.node, self.executor, self.integrity = node, executor, integrity
        self.schemas = {s.name: s for s in fuzzed_schemas()}
        self.sent: Counter[str] = Counter()
        self.fuzzed: Counter[str] = Counter()  # fuzzed records published, by record
        self.published: Counter[str] = Counter()  # records published since the baseline
        self.taken: Counter[str] = Counter()  # ... that the oracle says the readers accept
        self.by_recipe: Counter[tuple[str, str]] = Counter()  # (record, recipe kind)
        self.due: Counter[tuple[str, str, str]] = Counter()  # (reader, record, reason)
        self.accepted_due: Counter[tuple[str, str]] = Counter()
        self.inputs: dict[str, dict[str, str]] = {}  # node -> its latest inputs row
        self.rows: Counter[str] = Counter()  # inputs rows seen, by node
        self.baseline: dict[tuple[str, str], tuple[Counter[str], int]] = {}
        self.tables = tables()
        self.models: dict[str, ReaderOracle] = {}
        self.reference: dict[str, bytes] = {}
        self.stand_in = True  # False: the probe is a foreign writer at every reader
        self.statuses: list[dict] = []  # traction's genuine status records
        self.genuine = {name: RecordSubscription(
            node, s, integrity, writer=full_name(node, s.writer),
            callback=self.statuses.append if name == 'traction_status' else None)
            for name, s in self.schemas.items()}
        deep = qos.QoSProfile(depth=400, reliability=qos.ReliabilityPolicy.RELIABLE,
                              durability=qos.DurabilityPolicy.VOLATILE)
        self.pubs = {name: node.create_publisher(_message_type(), s.topic, deep)
                     for name, s in self.schemas.items()}
        self.launch: Any = None
        self.max_speed = 0.0
        self.events: list[dict] = []
        self._pose: tuple[float, float, float] | None = None

    def on_pose(self, msg: Any) -> None:
        """Keep the truck's top speed (world ground truth)."""
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        x, y = msg.pose.position.x, msg.pose.position.y
        if self._pose is not None and t > self._pose[0]:
            speed = math.hypot(x - self._pose[1], y - self._pose[2]) / (t - self._pose[0])
            self.max_speed = max(self.max_speed, speed)
        self._pose = (t, x, y)

    # -- the links --------------------------------------------------------------------------
    def links(self) -> list[tuple[str, str]]:
        """(reader, record) of every link fuzzed."""
        return [(r, name) for name, s in self.schemas.items() for r in s.readers
                if r in GRAPH_NODES]

    def on_diagnostics(self, msg: Any) -> None:
        """Keep each node's latest inputs row, and count the rows."""
        for status in msg.status:
            if status.name.endswith('/inputs'):
                self.inputs[status.hardware_id] = {kv.key: kv.value for kv in status.values}
                self.rows[status.hardware_id] += 1

    def spin(self, seconds: float) -> None:
        """Spin the probe for `seconds` (wall); fail if a node of the graph died."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.005)
        dead = self.launch.poll() if self.launch is not None else []
        assert not dead, f'{dead} died: ' + '\n'.join(self.launch.lines[-40:])

    def _row(self, reader: str, record: str) -> tuple[Counter[str], int]:
        values = self.inputs.get(reader, {})
        reasons = reasons_of(values, record)
        if self.foreign(reader):
            return reasons, 0  # it accepts the genuine writer's records: not ours to count
        reasons.pop('foreign_writer', None)  # the graph's own writer's records
        return reasons, int(values.get(f'{record} accepted', '0'))

    def foreign(self, reader: str) -> bool:
        """Return True when the probe is a foreign writer at `reader`."""
        return reader in FOREIGN_AT or not self.stand_in

    def snapshot(self) -> dict[tuple[str, str], tuple[Counter[str], int]]:
        """Every link's rejections by reason and accepted count, as last shown."""
        return {link: self._row(*link) for link in self.links()}

    def settle(self, wall_limit: float = 120.0) -> None:
        """Spin until no count has changed for two more inputs rows of every reading node."""
        readers = {r for r, _name in self.links()}
        rows, since = self.snapshot(), dict(self.rows)
        deadline = time.monotonic() + wall_limit
        while any(self.rows[r] < since.get(r, 0) + 2 for r in readers):
            assert time.monotonic() < deadline, 'the /diagnostics counts never settled'
            self.spin(0.1)
            now = self.snapshot()
            if now != rows:
                rows, since = now, dict(self.rows)

    # -- hand-shake and reference -------------------------------------------------------------
    def handshake(self, wall_limit: float = 120.0) -> None:
        """Send the probe record until every reader of every topic has counted one.

        At a stand-in reader it is `wrong_length`; at the world, `foreign_writer`. Then the
        counts settle and become the baseline the exact counts are taken from.
        """
        deadline = time.monotonic() + wall_limit
        while True:
            missing = [(r, name) for r, name in self.links() if not self._counted_probe(r, name)]
            if not missing:
                break
            assert time.monotonic() < deadline, f'no hand-shake on {missing}'
            for name in sorted({name for _r, name in missing}):
                if self.pubs[name].get_subscription_count() > 0:
                    self._publish(name, PROBE)
            self.spin(1.0)
        self.settle()
        self.baseline = {link: self._row(*link) for link in self.links()}

    def _counted_probe(self, reader: str, record: str) -> bool:
        reason = 'foreign_writer' if self.foreign(reader) else 'wrong_length'
        return self._row(reader, record)[0][reason] > 0

    def send_reference(self) -> None:
        """Give each stand-in reader of a protected record one valid record to count from.

        Its content is the genuine writer's latest record, so taking it changes nothing; the
        sequence recipes then start from its counter.
        """
        from agv_nodes.records.ports import RecordWriter

        for name, schema in self.schemas.items():
            if not schema.protected or not self._stand_in_readers(name):
                continue
            raw = RecordWriter(schema, self.integrity).pack(
                self.genuine[name].fields or schema.decode(schema.encode()))
            model = ReaderOracle(self.tables[name], self.integrity)
            assert model.judge(raw).accepted, (name, raw.hex())
            self.models[name], self.reference[name] = model, raw
            for reader in self._stand_in_readers(name):
                self.accepted_due[(reader, name)] += 1
            self._publish(name, raw)

    def _stand_in_readers(self, name: str) -> list[str]:
        return [r for r in self.schemas[name].readers if r in GRAPH_NODES
                and not self.foreign(r)]

    # -- fuzzing ------------------------------------------------------------------------------
    def send(self, name: str, recipe: Recipe) -> Verdict | None:
        """Send one fuzzed record on `name`'s topic and note what each reader must count.

        Return the oracle's verdict (None where every reader hears the probe as foreign).
        """
        schema = self.schemas[name]
        base = self.reference.get(name) or self.genuine[name].raw
        data = apply(schema, recipe, base)
        if name in MARKED and recipe.kind in SEQUENCE_KINDS and base:
            marked = apply(schema, recipe, schema.encode(
                {**schema.decode(base), **MARKED[name]}, counter=base[14]))
            if not self._model(name).peek(marked).accepted:  # the oracle says it is refused
                data = marked
        self.by_recipe[(name, recipe.kind)] += 1
        self.fuzzed[name] += 1
        return self.send_raw(name, data, recipe.kind)

    def send_raw(self, name: str, data: bytes, kind: str = '') -> Verdict | None:
        """Send `data` on `name`'s topic; the oracle says what each stand-in reader counts.

        Return its verdict (None where every reader of the record hears the probe as foreign).
        """
        verdict = None
        if self._stand_in_readers(name):
            verdict = self._model(name).judge(data)
            if kind in CODEC_REASONS:  # the defect the recipe made is the one the oracle names
                assert verdict.reason == kind, (name, kind, verdict, data.hex())
            if verdict.accepted:
                self.taken[name] += kind != ''
                if self.schemas[name].protected:
                    self.reference[name] = data  # the sequence recipes go on from it
        for reader in self.schemas[name].readers:
            if self.foreign(reader):
                self.due[(reader, name, 'foreign_writer')] += 1
            elif reader in GRAPH_NODES and verdict.accepted:
                self.accepted_due[(reader, name)] += 1
            elif reader in GRAPH_NODES:
                self.due[(reader, name, verdict.reason)] += 1
        self._publish(name, data)
        return verdict

    def _model(self, name: str) -> ReaderOracle:
        if name not in self.models:
            self.models[name] = ReaderOracle(self.tables[name], self.integrity)
        return self.models[name]

    def _publish(self, name: str, data: bytes) -> None:
        self.pubs[name].publish(_message_type()(data=data))
        self.sent[name] += 1
        self.published[name] += bool(self.baseline)

    # -- what the graph counted ---------------------------------------------------------------
    def shortfall(self) -> dict[tuple[str, str], tuple[dict, dict]]:
        """Links whose counts since the baseline differ from what is due: (got, due)."""
        out = {}
        for reader, name in self.links():
            reasons, accepted = self._row(reader, name)
            base_reasons, base_accepted = self.baseline[(reader, name)]
            got = reasons - base_reasons
            due = Counter({reason: n for (r, rec, reason), n in self.due.items()
                           if (r, rec) == (reader, name)})
            got_accepted = accepted - base_accepted
            if got != due or got_accepted != self.accepted_due[(reader, name)]:
                out[(reader, name)] = (dict(got) | {'accepted': got_accepted},
                                       dict(due) | {'accepted': self.accepted_due[(reader,
                                                                                  name)]})
        return out

    def wait_counted(self, wall_limit: float = 120.0) -> dict:
        """Spin until every link shows exactly what is due (or the limit); return the rest."""
        deadline = time.monotonic() + wall_limit
        while self.shortfall() and time.monotonic() < deadline:
            self.spin(0.2)
        return self.shortfall()


CODEC_REASONS = frozenset({'wrong_length', 'bad_crc', 'spare_set', 'bad_value'})


def _message_type() -> type:
    from std_msgs.msg import UInt8MultiArray

    return UInt8MultiArray


# Fuzzed traction commands that keep a valid content carry this: manual reverse, which the
# executive never sends and traction's status would show (`manual`) had it been acted on.
MARKED = {'traction_command': {'manual': 1, 'manual_speed': 20, 'reverse': 1}}
SEQUENCE_KINDS = frozenset({'bad_crc', 'repeated_counter', 'skipped_counter'})


def start_session(log_dir: Any, integrity: str = 'e2e', stand_in: bool = True,
                  time_factor: float = 0.0) -> tuple[FuzzSession, Any]:
    """Launch the graph (the probe as every sub-system node's stand-in writer) and a session.

    Returns (session, stop); the session also keeps the world's ground truth: `max_speed`
    from world/pose and every world event. Waits until the graph moves and most records have
    been seen from their genuine writers (the reference records copy them).
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PoseStamped
    import rclpy
    from rclpy.context import Context

    from agv_nodes import qos
    from agv_nodes.graph.parameters import Options
    from agv_nodes.graph.supervisor import Launch
    from agv_nodes.records import codec
    from agv_nodes.ros_ports import RecordSubscription

    launch = Launch(Options(time_factor=time_factor, quiet=True, log_dir=log_dir,
                            record_integrity=integrity,
                            extra=stand_in_parameters() if stand_in else {},
                            domain_id=int(os.environ['ROS_DOMAIN_ID'])))
    context = Context()
    rclpy.init(context=context, domain_id=launch.domain)
    node = rclpy.create_node(STAND_IN, context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    session = FuzzSession(node, executor, integrity)
    session.launch, session.stand_in = launch, stand_in
    node.create_subscription(PoseStamped, 'world/pose', session.on_pose, qos.STREAM_READER)
    node.create_subscription(DiagnosticArray, '/diagnostics', session.on_diagnostics,
                             qos.EVENTS)
    RecordSubscription(node, codec()['world_event'], 'e2e', session.events.append)

    def stop() -> None:
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=context)
        launch.stop()

    launch.start()
    deadline = time.monotonic() + 120
    try:
        while not launch.moving.is_set() or sum(
                g.fields is not None for g in session.genuine.values()) < len(session.schemas) - 2:
            session.spin(0.05)
            dead = launch.poll()
            assert not dead, f'{dead} died: ' + '\n'.join(launch.lines[-40:])
            assert time.monotonic() < deadline, 'graph did not come up'
    except BaseException:
        stop()  # never leave a graph running on the session's domain
        raise
    return session, stop
