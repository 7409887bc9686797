"""Who may write a record topic (records.ports.WriterCheck), without DDS: a fake graph.

The graph is a list of (node, GID) the test edits as discovery would; the clock is the test's.
Restart against duplicate, writers named by GID, and the stop switches' rule (a foreign `true`
stops, a foreign `false` never releases) are judged here; test_duplicate_writer_dds.py,
test_plain_dds_driver_dds.py and test_foreign_writer_dds.py show them over DDS.
"""

from __future__ import annotations

import pytest

from agv_nodes.records import codec
from agv_nodes.records.ports import (
    DUPLICATE_WRITER,
    FOREIGN_WRITER,
    CheckedInput,
    RecordReader,
    SwitchInput,
    WriterCheck,
    inputs_report,
    node_name,
)

pytestmark = pytest.mark.timeout(60)

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


# -- restart against duplicate ----------------------------------------------------------------
# The graph and the samples are the test's: a restart is one endpoint of the writer's name
# that stops and another that starts; a duplicate is two that both keep sending.
SECOND = bytes([5]) * 16


def verdicts(check: WriterCheck, samples) -> list[str]:
    return [v for gid in samples for _d, _g, v in check.admit(b'r', gid)]


def test_two_live_endpoints_of_the_writer_are_a_duplicate_not_restarts():
    """Two executives: their records interleave. Today's 1,621 'restarts' are one duplicate."""
    g = Graph(('/executive', GENUINE), ('/executive', SECOND))
    check = g.check(requery_s=0.0)
    out = verdicts(check, [GENUINE, GENUINE, SECOND, GENUINE, SECOND, GENUINE, SECOND])
    # the second's first record is taken as a restart would be: nothing yet says the first
    # still writes; the first's next record does
    assert out == ['genuine', 'genuine', 'restart'] + [DUPLICATE_WRITER] * 4
    assert check.restarts == 1 and check.duplicate_samples == 4
    assert check.duplicates == [GENUINE, SECOND]
    text = check.duplicate_text('traction_command')
    assert GENUINE.hex() in text and SECOND.hex() in text and '/executive' in text
    # a foreign endpoint stays foreign, not part of the duplicate
    g.endpoints.append(('/intruder', OTHER))
    assert verdicts(check, [OTHER]) == [FOREIGN_WRITER]


def test_a_restart_is_no_duplicate_even_while_the_old_endpoint_lingers_in_the_graph():
    """A killed process's endpoint stays in the graph until its lease ends, but sends nothing."""
    g = Graph(('/executive', GENUINE))
    check = g.check(requery_s=0.0)
    g.endpoints.append(('/executive', RESTARTED))  # the old one still listed
    out = verdicts(check, [GENUINE, GENUINE, RESTARTED, RESTARTED, RESTARTED])
    assert out == ['genuine', 'genuine', 'restart', 'genuine', 'genuine']
    assert check.duplicates == [] and check.duplicate_text('x') == ''
    g.endpoints = [('/executive', SECOND)]  # a second restart (respawn again)
    assert verdicts(check, [SECOND, SECOND]) == ['restart', 'genuine']
    assert check.restarts == 2


def test_a_duplicate_stands_while_both_are_in_the_graph_and_ends_when_one_leaves():
    g = Graph(('/executive', GENUINE), ('/executive', SECOND))
    check = g.check(requery_s=1.0)
    verdicts(check, [GENUINE, SECOND, GENUINE])
    g.now += 5.0
    assert verdicts(check, [GENUINE, SECOND]) == [DUPLICATE_WRITER] * 2  # both still there
    g.endpoints = [('/executive', GENUINE)]  # the second executive quits
    g.now += 0.5
    assert verdicts(check, [GENUINE]) == [DUPLICATE_WRITER]  # not asked again yet
    g.now += 1.0
    # the graph shows one: it is the writer again, its counter taken afresh
    assert verdicts(check, [GENUINE, GENUINE]) == ['restart', 'genuine']
    assert check.duplicates == []


def test_a_third_live_endpoint_joins_the_duplicate():
    g = Graph(('/executive', GENUINE), ('/executive', SECOND), ('/executive', RESTARTED))
    check = g.check(requery_s=0.0)
    assert verdicts(check, [GENUINE, SECOND, GENUINE, RESTARTED])[-1] == DUPLICATE_WRITER
    assert check.duplicates == [GENUINE, SECOND, RESTARTED]


def test_a_reader_with_a_duplicate_is_an_error_in_the_inputs_report():
    schema = codec()['traction_command']
    reader = RecordReader(schema)
    reader.duplicate = 'traction_command: 2 live endpoints write as /executive: /executive (01..)'
    level, message, _values = inputs_report({'traction_command': reader})
    assert level == 2 and message.startswith('duplicate writer: traction_command: 2 live')
    reader.duplicate, reader.waiting = '', 'traction_command: waiting for its writer /executive'
    level, message, _values = inputs_report({'traction_command': reader})
    assert level == 1 and message.startswith('traction_command: waiting for its writer')


# -- a writer that is no ROS node ---------------------------------------------------------------
BARE = '_CREATED_BY_BARE_DDS_APP_/_CREATED_BY_BARE_DDS_APP_'  # the graph's name, no leading '/'


def test_names_compare_with_one_leading_slash():
    """The graph names a plain DDS writer without a leading '/'; a reader's name has one."""
    g = Graph((BARE, GENUINE))
    assert g.check('/' + BARE).admit(b'a', GENUINE) == [(b'a', GENUINE, 'genuine')]
    assert node_name(BARE) == '/' + BARE and node_name('//executive/') == '/executive'


def test_a_writer_named_by_its_gid_is_taken_at_once_whatever_the_graph_says():
    g = Graph((BARE, GENUINE), (BARE, OTHER))
    check = g.check(f'gid:{GENUINE.hex()}', patience_s=100.0)
    assert check.admit(b'a', GENUINE) == [(b'a', GENUINE, 'genuine')]
    assert check.admit(b'b', OTHER) == [(b'b', OTHER, FOREIGN_WRITER)]  # its own node: no
    unnamed = Graph().check(f'gid:{GENUINE.hex()}', patience_s=100.0)  # graph not caught up
    assert unnamed.admit(b'c', GENUINE) == [(b'c', GENUINE, 'genuine')]
    # a participant's prefix (12 bytes) admits each of its writers
    prefix = Graph().check(f'gid:{GENUINE[:12].hex()}')
    assert prefix.admit(b'd', GENUINE[:12] + bytes(4)) == [(b'd', GENUINE[:12] + bytes(4),
                                                            'genuine')]


def test_record_writers_takes_gid_entries_and_switches_and_refuses_bad_hex():
    from agv_nodes.settings import NodeSettings, SettingError, build

    ok = build(NodeSettings, {'record_writers': [f'adc_snapshot=gid:{GENUINE.hex()}',
                                                 'radio_stop=radio_board']})
    assert ok.writer_nodes() == {'adc_snapshot': f'gid:{GENUINE.hex()}',
                                 'radio_stop': 'radio_board'}
    for bad in ('adc_snapshot=gid:xyz', 'adc_snapshot=gid:' + '00' * 17, 'clock=world'):
        with pytest.raises(SettingError, match='record_writers'):
            build(NodeSettings, {'record_writers': [bad]})


# -- the stop switches ----------------------------------------------------------------------------
def switch(*endpoints: tuple[str, bytes], patience_s: float = 2.0) -> tuple[Graph, SwitchInput]:
    g = Graph(*endpoints)
    return g, SwitchInput('radio_stop', g.check('/radio_receiver', requery_s=0.0,
                                                patience_s=patience_s))


def test_a_foreign_stop_is_taken_and_counted_but_a_foreign_release_is_refused():
    _g, radio = switch(('/radio_receiver', GENUINE), ('/intruder', OTHER))
    assert radio.take(True, GENUINE, 1) == [True]
    assert radio.take(False, OTHER, 2) == []  # cannot release the genuine stop
    assert radio.take(False, GENUINE, 3) == [False]
    assert radio.take(True, OTHER, 4) == [True]  # a stop is never refused
    assert radio.take(False, OTHER, 5) == []
    assert radio.value is True
    assert radio.rejects == {'foreign_stop_taken': 1, FOREIGN_WRITER: 2}
    assert radio.accepted == 2 and 'refused' in radio.last_error and '/intruder' in \
        radio.last_error
    level, message, values = inputs_report({'radio_stop': radio})
    assert level == 1 and values['radio_stop rejects by reason'] == \
        'foreign_stop_taken=1, foreign_writer=2'
    assert radio.take(False, GENUINE, 6) == [False]  # only the writer releases


def test_a_stop_from_an_endpoint_the_graph_has_not_named_is_taken_at_once():
    g, radio = switch(('/radio_receiver', GENUINE))
    assert radio.take(True, LATE, 1) == [True]  # held for the graph, acted on all the same
    assert radio.take(False, LATE, 2) == []  # held: not acted on before it is judged
    g.now = 3.0  # past the patience: foreign, its release refused
    assert radio.take(False, LATE, 3) == []
    assert radio.rejects == {'foreign_stop_taken': 1, FOREIGN_WRITER: 2}


def test_a_genuine_release_held_for_the_graph_does_not_undo_a_later_stop():
    g, radio = switch(('/_NODE_NAME_UNKNOWN_', LATE))
    assert radio.take(False, LATE, 1) == []  # the writer's release, its node not yet named
    assert radio.take(True, OTHER, 2) == [True]  # someone's stop, acted on at once
    g.endpoints = [('/radio_receiver', LATE), ('/intruder', OTHER)]
    assert radio.take(True, LATE, 3) == [True]  # the held release is judged: it came first
    assert radio.value is True and radio.accepted == 2


def test_duplicate_radio_receivers_cannot_release_and_are_an_error():
    _g, radio = switch(('/radio_receiver', GENUINE), ('/radio_receiver', SECOND))
    assert radio.take(False, GENUINE, 1) == [False]
    assert radio.take(False, SECOND, 2) == [False]  # taken as a restart
    assert radio.take(False, GENUINE, 3) == []  # both send: a duplicate
    assert radio.take(True, SECOND, 4) == [True]
    assert radio.take(False, SECOND, 5) == []
    assert radio.rejects[DUPLICATE_WRITER] == 2 and radio.duplicate
    assert inputs_report({'radio_stop': radio})[0] == 2


def test_a_camera_frame_from_another_endpoint_is_refused_and_named():
    """hw/camera/<name> (route following steers by it): only the named writer's frames."""
    g = Graph(('/world', GENUINE), ('/intruder', OTHER))
    frames = CheckedInput('camera_front', g.check('/world'))
    assert frames.take(b'frame 1', GENUINE, 1) == [b'frame 1']
    assert frames.take(b'forged', OTHER, 2) == []
    assert frames.accepted == 1 and frames.rejects == {FOREIGN_WRITER: 1}
    assert frames.last_error == (f'camera_front: from /intruder ({OTHER.hex()}), not the '
                                 'writer /world')
    assert inputs_report({'camera_front': frames})[2]['camera_front writer'] == \
        f'/world ({GENUINE.hex()})'
