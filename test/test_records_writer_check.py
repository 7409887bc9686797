"""Who may write a record topic (records.ports.WriterCheck), without DDS: a fake graph.

The graph is a list of (node, GID) the test edits as discovery would; the clock is the test's.
"""

from __future__ import annotations

from agv_nodes.records import codec
from agv_nodes.records.ports import FOREIGN_WRITER, RecordReader, WriterCheck, inputs_report

GENUINE, OTHER, LATE, RESTARTED = (bytes([k]) * 16 for k in (1, 2, 3, 4))


class Graph:
    """A fake graph and clock: what `lookup` returns, and how often it was asked."""

    def __init__(self, *endpoints: tuple[str, bytes]) -> None:
        self.endpoints = list(endpoints)
        self.now = 0.0
        self.asked = 0

    def lookup(self) -> list[tuple[str, bytes]]:
        self.asked += 1
        return list(self.endpoints)

    def check(self, writer: str = '/executive', **kw) -> WriterCheck:
        return WriterCheck(writer, self.lookup, clock=lambda: self.now, **kw)


def test_the_named_writer_is_genuine_and_every_other_endpoint_foreign():
    g = Graph(('/executive', GENUINE), ('/intruder', OTHER))
    check = g.check()
    assert check.admit(b'a', GENUINE) == [(b'a', GENUINE, 'genuine')]
    assert check.admit(b'b', OTHER) == [(b'b', OTHER, FOREIGN_WRITER)]
    assert check.current == GENUINE and check.nodes[OTHER] == '/intruder'
    # a node of the same name in another namespace is another node
    other_ns = Graph(('/agv2/executive', OTHER)).check()
    assert other_ns.admit(b'c', OTHER) == [(b'c', OTHER, FOREIGN_WRITER)]


def test_the_graph_is_asked_only_for_a_new_gid_and_at_most_once_per_requery_period():
    g = Graph(('/executive', GENUINE))
    check = g.check(requery_s=0.5, patience_s=100.0)
    for _ in range(100):
        check.admit(b'a', GENUINE)
    assert g.asked == 1
    for k in range(100):  # 25 s of a flood from an endpoint the graph does not name
        g.now += 0.25
        check.admit(b'x', LATE)
        if k == 0:
            assert g.asked == 1  # 0.25 s after the first query: not yet
    assert g.asked == 1 + 50  # every 0.5 s, not per sample


def test_a_writer_the_graph_names_late_is_held_then_released_in_order_not_rejected():
    g = Graph(('/executive', GENUINE), ('/executive', LATE.replace(b'\x03', b'\x09', 1)))
    g.endpoints.append(('/_NODE_NAME_UNKNOWN_', LATE))  # discovery lag: GID known, node not
    check = g.check(requery_s=0.2)
    assert check.admit(b'1', LATE) == []
    g.now = 0.1
    assert check.admit(b'2', LATE) == []  # not asked again yet
    g.endpoints[-1] = ('/executive', LATE)  # the graph learns the node
    g.now = 0.25
    assert check.admit(b'3', LATE) == [(b'1', LATE, 'genuine'), (b'2', LATE, 'genuine'),
                                       (b'3', LATE, 'genuine')]
    assert check.held == 2


def test_an_endpoint_the_graph_never_names_is_foreign_after_the_patience():
    g = Graph(('/executive', GENUINE))  # a plain DDS writer never shows a node
    check = g.check(requery_s=0.2, patience_s=2.0)
    out = []
    for _ in range(30):
        out += check.admit(b'x', OTHER)
        g.now += 0.1
    assert [v for _d, _g, v in out] == [FOREIGN_WRITER] * 30
    assert OTHER not in check.nodes
    assert check.admit(b'y', OTHER) == [(b'y', OTHER, FOREIGN_WRITER)]


def test_a_genuine_writer_named_only_after_the_patience_is_then_taken():
    """A loaded machine may name the writer late: its records flow from then on."""
    g = Graph()
    check = g.check(requery_s=0.2, patience_s=2.0)
    out = []
    for _ in range(30):  # 3 s unnamed: held, then foreign
        out += check.admit(b'x', GENUINE)
        g.now += 0.1
    assert out and {v for _d, _g, v in out} == {FOREIGN_WRITER}
    g.endpoints.append(('/executive', GENUINE))
    g.now += 0.3
    assert check.admit(b'y', GENUINE)[-1] == (b'y', GENUINE, 'genuine')


def test_past_the_hold_the_oldest_waiting_sample_is_rejected_as_foreign():
    g = Graph()
    check = g.check(hold=3)
    out = []
    for k in range(5):
        out += check.admit(bytes([k]), OTHER)
    assert out == [(b'\x00', OTHER, FOREIGN_WRITER), (b'\x01', OTHER, FOREIGN_WRITER)]


def test_a_restarted_writer_is_followed_at_once_and_its_old_gid_is_not_current():
    g = Graph(('/executive', GENUINE))
    check = g.check(requery_s=0.0)
    check.admit(b'a', GENUINE)
    g.endpoints = [('/executive', RESTARTED)]  # agv-launch --respawn: a new process
    assert check.admit(b'b', RESTARTED) == [(b'b', RESTARTED, 'restart')]
    assert check.current == RESTARTED and check.restarts == 1
    assert check.admit(b'c', RESTARTED) == [(b'c', RESTARTED, 'genuine')]


def test_a_reader_resyncs_its_counter_for_a_restarted_writer():
    """What RecordSubscription does with 'restart': the new counter is taken at once."""
    schema = codec()['traction_command']
    reader = RecordReader(schema)
    assert reader.accept(schema.encode({'demand': 10}, counter=200), 0) is not None
    jumped = schema.encode({'demand': 10}, counter=3)
    assert reader.accept(jumped, 1) is None and reader.last_reason == 'wrong_sequence'
    reader.resync()
    assert reader.accept(schema.encode({'demand': 10}, counter=4), 2) is not None
    assert reader.restarted and reader.restarts == 1  # its node hears of the new writer
    assert reader.accept(schema.encode({'demand': 10}, counter=5), 3) is not None
    assert not reader.restarted


def test_a_writer_restarted_without_a_new_gid_is_known_by_its_counter_run():
    """A driver board that resets behind the same endpoint: its counter restarts from 0."""
    schema = codec()['traction_command']
    reader = RecordReader(schema)
    for k in range(50, 53):
        assert reader.accept(schema.encode({'demand': 10}, counter=k), k) is not None
        assert not reader.restarted  # the first writer ever heard is no restart
    taken = [reader.accept(schema.encode({'demand': 10}, counter=k), 100 + k) for k in range(3)]
    assert taken[:2] == [None, None] and taken[2] is not None
    assert reader.restarted and reader.restarts == 1
    plain = RecordReader(schema, 'none')  # without counters only resync() can tell
    plain.accept(schema.encode({'demand': 10}, integrity='none'), 0)
    plain.resync()
    plain.accept(schema.encode({'demand': 10}, integrity='none'), 1)
    assert plain.restarted and plain.restarts == 1


def test_foreign_writer_rejections_are_shown_in_the_inputs_report_like_every_reason():
    schema = codec()['traction_status']
    reader = RecordReader(schema)
    reader._reject(FOREIGN_WRITER, 'traction_status: from /intruder')
    level, message, values = inputs_report({'traction_status': reader})
    assert level == 1 and 'foreign_writer=1' in message
    assert values['traction_status rejects by reason'] == 'foreign_writer=1'
    assert 'traction_status writer' not in values  # no endpoints without DDS (the harness)
