"""Bad records over DDS: every one counted, by reason and exactly, and never acted on.

The whole graph runs (one process per node, config/graph.yaml) with the truck at rest and no
task. A reader hears only its topic's named writer (records.ports.WriterCheck): records from
any other endpoint are rejected as `foreign_writer` before the codec sees them. So, to fuzz
the codec and the E2E checks over DDS, this test's probe node stands in as the named writer
(`record_writers`) of every record a sub-system node reads (test/fuzz_session.py); the graph's
own writers of those records are then foreign there. The world keeps its schema writers, so on
the three records it reads the probe is a foreign writer: that is the foreign part.

1. Hand-shake: a too-short probe record on every topic, sent until each reader has counted
   it (`wrong_length` at a stand-in reader, `foreign_writer` at the world); the counts then
   settle and are the baseline. Then one valid reference record per protected topic (a copy
   of the genuine writer's latest), which the sequence defects count from.
2. Hypothesis draws one malformed record per topic per example (test/record_fuzz.py: wrong
   lengths, random bytes, bad CRC, replayed and skipped counters, spare bits, out-of-range
   values), and every one drawn is sent. What each reader must do with it is the verdict of
   an oracle written apart from the codec and the reader (test/record_oracle.py: the tables
   of msg_schemas/ and the rules of docs/records.md), which sees the same records in the same
   order: rejected by reason, or accepted (a skipped counter that completes a
   resynchronisation run is a writer by the rules); a recipe's own codec defect must be the
   reason it names.
3. Every reader's `/diagnostics` row must then show exactly the oracle's totals per topic:
   its rejections by reason since the baseline and its accepted count (the reference and what
   the oracle accepts), and so every record sent is accounted for. An accepted one carries
   the content of the last record taken, and fuzzed traction commands the oracle refuses ask
   for manual reverse, which traction's status never shows; the world's ground truth shows
   the truck never moved and nothing happened, and no node died.

`AGV_FUZZ_EXAMPLES` sets the number of examples (default 150: 3,000 records on 20 topics);
bench/fuzz_bench.py sends 100,000 and writes bench/results/fuzz_bench.md.
"""

from __future__ import annotations

import os
import signal
import time

from fuzz_session import fuzzed_schemas, start_session
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import pytest
from record_fuzz import Recipe, recipes

from agv_nodes.records.codec import codec

pytestmark = [pytest.mark.dds, pytest.mark.slow]

EXAMPLES = int(os.environ.get('AGV_FUZZ_EXAMPLES', '150'))
FUZZED = fuzzed_schemas()


def test_legacy_graph_rejects_a_foreign_writer_but_obeys_one_named_as_its_writer(
        tmp_path, fault_table):
    """record_integrity none (a legacy 1983 peer): what the writer check does and does not do.

    Plain thesis records carry no CRC, so only the writer check stands between a second
    process and the truck. A node of another name is rejected (`foreign_writer`); once the
    genuine executive has gone, a node that takes its name in the graph is its writer and is
    obeyed - the documented risk of `none` (docs/hardware.md: only access control stops it;
    while the genuine one runs, two of that name are a `duplicate_writer` fault, shown in
    test_duplicate_writer_dds.py). The test proves both, so the documentation cannot go
    stale. (First in the module: it runs its own graph on the session's domain before the
    module's graph starts.)
    """
    import rclpy

    from agv_nodes.ros_ports import RecordPublisher

    session, stop = start_session(tmp_path / 'logs', integrity='none', stand_in=False)
    schema = codec()['traction_command']
    impostor = rclpy.create_node('executive', context=session.node.context)
    try:
        session.handshake()
        plain = [{'demand': 0 if k < 4 else 55} for k in range(40)]  # 00H clears a trip latch
        for fields in plain:  # from the probe, a node of another name
            session.send_raw('traction_command', schema.encode(fields, integrity='none'))
            session.spin(0.05)
        left = session.wait_counted()
        assert not left, f'not counted exactly (got, due): {left}'
        foreign = session.due[('traction', 'traction_command', 'foreign_writer')]
        assert foreign == len(plain)
        # the genuine executive leaves (an exit asked for, not a death); then the same records
        # from a node named as the executive
        genuine = session.launch.procs['executive']
        genuine.send_signal(signal.SIGINT)
        genuine.wait(timeout=30)
        session.launch.exits['executive'] = genuine.returncode
        pub = RecordPublisher(impostor, schema, 'none')
        wait(session, lambda: pub.subscription_count > 0, 'the impostor matched')
        first = steady(session, 'traction', 'traction_command accepted')
        for fields in plain:
            pub.publish(fields)
            session.spin(0.05)
        wait(session, lambda: int(session.inputs['traction']['traction_command accepted'])
             >= first + len(plain), "traction counting the impostor's commands as accepted")
        accepted = steady(session, 'traction', 'traction_command accepted') - first
        assert accepted == len(plain)
        assert not session.wait_counted(), 'the impostor was counted as foreign'
    finally:
        impostor.destroy_node()
        stop()
    fault_table.add('plain traction_command, record_integrity none: from a node of another '
                    'name, and, the executive gone, from a node named as the executive',
                    'another node: rejected (foreign_writer); one named as the executive: '
                    'accepted (the documented risk of a legacy peer, docs/hardware.md)',
                    f'{foreign} of 40 foreign_writer; the impostor: {accepted} of 40 '
                    'accepted, none rejected')


@pytest.fixture(scope='module')
def session(tmp_path_factory):
    s, stop = start_session(tmp_path_factory.mktemp('fuzz') / 'logs')
    try:
        s.handshake()
        s.send_reference()
        yield s
    finally:
        stop()


BATCH = st.fixed_dictionaries({s.name: recipes(s) for s in FUZZED})


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(batch=BATCH)
def test_fuzz_every_record_topic(session, batch):
    for name, recipe in batch.items():
        session.send(name, recipe)
    session.spin(0.04)  # paced so that no reader's queue overflows: every record arrives


def test_every_fuzzed_one_was_counted_exactly_and_never_acted_on(session, fault_table):
    drawn = sum(session.by_recipe.values())
    sent = sum(session.fuzzed.values())
    assert sent == drawn >= EXAMPLES * len(FUZZED), 'every record drawn is sent'
    left = session.wait_counted()
    assert not left, f'counts since the hand-shake differ (got, due): {left}'
    for reader, name in session.links():  # each record published is one count at each reader
        judged = sum(n for (r, rec, _), n in session.due.items() if (r, rec) == (reader, name))
        assert judged + session.accepted_due[(reader, name)] == session.published[name], \
            (reader, name)
    manual = [s for s in session.statuses if s['manual']]
    assert session.statuses and not manual, manual[:3]
    assert session.max_speed < 0.005, f'the truck moved ({session.max_speed:.3f} m/s)'
    assert not session.events, f'something happened in the world: {session.events}'
    # the graph's own writers are foreign at the stand-in readers: the check is on
    theirs = {link for link in session.links() if link[0] != 'world'
              and 'foreign_writer' in session.inputs[link[0]].get(f'{link[1]} rejects by '
                                                                  'reason', '')}
    assert len(theirs) >= len(session.links()) - 3 - 2, theirs
    reasons = sorted({reason for (_r, _n, reason) in session.due})
    taken = sum(session.taken.values())
    print(f'{sent} fuzzed records on {len(FUZZED)} topics, all sent: {taken} accepted as the '
          f'oracle says, the rest counted exactly by reason ({", ".join(reasons)})')
    fault_table.add('malformed records on every record topic: from the named writer (a '
                    'stand-in) and, at the world, from a foreign one',
                    "each counted by the independent oracle's reason (or accepted where it "
                    'says), exactly; none acted on; truck never moves; no node dies',
                    f'{sent} records on {len(FUZZED)} topics, all sent ({taken} accepted as '
                    'resynchronised): counts exact, truck at rest')


@pytest.mark.timeout(300)
def test_a_run_of_jumped_counters_is_taken_as_the_oracle_says(session, fault_table):
    """Three records in a row past the window: refused, refused, then taken (a new writer).

    Each topic's run jumps from the record the readers took last, clear of the runs the fuzzing
    left open (which it would join); its records carry that record's content, so taking the
    third changes nothing the node acts on.
    """
    runs = {}
    for name in sorted(session.reference):
        model = session.models[name]
        ends = {run.last for run in model.runs}
        skip = next(k for k in range(100, 200)
                    if not ends & {(model.reference + k + d) % 256 for d in range(-1, 3)})
        runs[name] = [session.send(name, Recipe(kind='skipped_counter', skip=skip + k))
                      for k in range(3)]
        session.spin(0.05)
    reasons = {name: [v.reason or 'accepted' for v in run] for name, run in runs.items()}
    assert all(r == ['wrong_sequence', 'resyncing', 'accepted'] for r in reasons.values()), \
        reasons
    left = session.wait_counted()
    assert not left, f'counts since the hand-shake differ (got, due): {left}'
    session.spin(0.5)
    assert session.max_speed < 0.005 and not session.events
    assert not [s for s in session.statuses if s['manual']]
    fault_table.add('three records in a row past the counter window (a restarted writer) on '
                    'every protected topic, from the named writer',
                    'first wrong_sequence, second resyncing, third taken, as the independent '
                    'oracle says; counted exactly; truck at rest',
                    f'{len(runs)} topics: each run counted exactly, the third accepted')


def test_named_writers_plain_traction_command_is_rejected_under_e2e(session, fault_table):
    """Even the named writer's plain 1983 records (no CRC) do not drive under e2e."""
    schema = codec()['traction_command']
    for k in range(40):  # 00H (clears a trip latch) then 55 %, 20 Hz for 2 s
        data = schema.encode({'demand': 0 if k < 4 else 55}, integrity='none')
        session.send_raw('traction_command', data)
        session.spin(0.05)
    left = session.wait_counted()
    assert not left, f'counts since the hand-shake differ (got, due): {left}'
    session.spin(0.5)  # and the truck has had time to (not) move
    assert session.max_speed < 0.005
    due = session.due[('traction', 'traction_command', 'bad_crc')]
    fault_table.add('plain traction_command (no CRC) from its named writer, record_integrity '
                    'e2e', 'rejected (bad_crc), counted, truck does not move',
                    f'40 sent, counted exactly ({due} bad_crc in the session), truck at rest')


def wait(session, condition, what: str, wall_limit: float = 60.0) -> None:
    """Spin `session` until `condition()`."""
    deadline = time.monotonic() + wall_limit
    while not condition():
        assert time.monotonic() < deadline, what
        session.spin(0.05)



def steady(session, reader: str, key: str, wall_limit: float = 60.0) -> int:
    """Return `key` of `reader`'s inputs row once two more rows have shown it unchanged."""
    deadline = time.monotonic() + wall_limit
    value, since = session.inputs[reader][key], session.rows[reader]
    while session.rows[reader] < since + 2:
        assert time.monotonic() < deadline, f'{reader}: {key} never settled'
        session.spin(0.1)
        if session.inputs[reader][key] != value:
            value, since = session.inputs[reader][key], session.rows[reader]
    return int(value)
