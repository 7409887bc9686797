"""Who may write a record topic, over DDS: only the graph's named writer is heard.

The whole graph runs (one process per node, sim time, demo_1983; test/graph_probe.py). A second
writer in this test process publishes on a record topic next to the genuine one:

- it forges VALID traction commands (right CRC, the genuine stream's next counter) while the
  truck cruises a task: E2E alone would take them, and the genuine writer's next record would
  be the rejected repeat. Every forged record must be counted `foreign_writer` at traction,
  none acted on (they ask for manual reverse, which traction's status would show), and the
  genuine stream must lose nothing: the task completes with its usual stop;
- it floods the executive's traction_status with bad records at eight times the executive's
  rejection budget: every one is counted `foreign_writer` and the budget, which is there for
  the genuine writer's own faults (test_faults_dds.py), never sees them: the task completes;
- a driver swap (`record_writers`): traction told to take its commands from a stand-in node
  accepts the stand-in's records and counts the executive's as foreign.

Each writer hand-shakes first: one record of it must be counted by the reader before the
records that are counted exactly are sent (a writer's records before the reader matched it
are lost). The counts are exact: the test is the only foreign writer on the domain.
"""

from __future__ import annotations

import time

from graph_probe import STOP_TOLERANCE_MM, GraphProbe
import pytest

from agv_nodes.records import codec

pytestmark = [pytest.mark.dds, pytest.mark.slow]

TASK = 'stop at 2 second'


def reasons(g: GraphProbe, node: str, record: str) -> dict[str, int]:
    """Rejections by reason of `record` in `node`'s latest /diagnostics inputs row."""
    text = g.inputs.get(node, {}).get(f'{record} rejects by reason', 'none')
    return {} if text == 'none' else {k: int(v) for k, v in
                                      (item.split('=') for item in text.split(', '))}


def held_for_the_graph(g: GraphProbe) -> dict[str, int]:
    """'node:record' -> genuine samples that waited for the graph to name their writer."""
    out = {}
    for node, values in g.inputs.items():
        for key, value in values.items():
            if key.endswith(' writer') and ' held for the graph' in value:
                out[f'{node}:{key[:-len(" writer")]}'] = int(value.split('; ')[1].split()[0])
    return out


def foreign_publisher(g: GraphProbe, topic: str):
    """Return a reliable volatile writer on the probe's node, deep enough for a burst."""
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos

    deep = qos.QoSProfile(depth=400, reliability=qos.ReliabilityPolicy.RELIABLE,
                          durability=qos.DurabilityPolicy.VOLATILE)
    return g.node.create_publisher(UInt8MultiArray, topic, deep)


def spin_for(g: GraphProbe, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        g.executor.spin_once(timeout_sec=0.01)


def send(pub, data: bytes) -> None:
    from std_msgs.msg import UInt8MultiArray

    pub.publish(UInt8MultiArray(data=data))


def handshake(g: GraphProbe, pub, node: str, record: str, data: bytes) -> None:
    """Send `data` until `node` counts one foreign record: the link is matched both ways."""
    deadline = time.monotonic() + 60
    while pub.get_subscription_count() == 0:
        g.executor.spin_once(timeout_sec=0.05)
        assert time.monotonic() < deadline, f'{record}: no reader matched the foreign writer'
    send(pub, data)
    g.spin_until(lambda: reasons(g, node, record).get('foreign_writer', 0) >= 1, 60,
                 f'{node} counting the hand-shake record on {record}')
    assert reasons(g, node, record).get('foreign_writer') == 1, g.inputs[node]


def settled(g: GraphProbe, read, what: str) -> int:
    """Return `read()` once it has stayed the same over two sim seconds (two inputs rows)."""
    value, since = read(), g.time
    deadline = time.monotonic() + 60
    while g.time < since + 2.0:
        g.executor.spin_once(timeout_sec=0.05)
        if read() != value:
            value, since = read(), g.time
        assert time.monotonic() < deadline, f'{what} did not settle'
    return value


def counted_foreign(g: GraphProbe, node: str, record: str, want: int) -> dict[str, int]:
    """Wait until `node` counts `want` foreign records and no more come; return the reasons."""
    deadline = time.monotonic() + 60
    while reasons(g, node, record).get('foreign_writer', 0) < want:
        g.executor.spin_once(timeout_sec=0.05)
        assert time.monotonic() < deadline, (f'{node} counted {reasons(g, node, record)} '
                                             f'of {want} foreign {record} records')
    settled(g, lambda: reasons(g, node, record).get('foreign_writer', 0), f'{node} {record}')
    return reasons(g, node, record)


def completed_with_usual_stop(g: GraphProbe) -> int:
    g.report_with(f"'{TASK}': completed", wall_limit=180)
    assert not [r for r in g.reports if 'FAILED' in r], g.reports
    stops = [e for _t, e in g.events if e['event'] == 'stopped']
    assert stops and abs(stops[-1]['error']) <= STOP_TOLERANCE_MM, stops
    return stops[-1]['error']


def test_forged_valid_traction_commands_are_foreign_and_never_acted_on(tmp_path, fault_table):
    from agv_nodes.ros_ports import RecordSubscription

    c = codec()
    schema = c['traction_command']
    g = GraphProbe(tmp_path / 'logs')
    try:
        # the genuine stream, as only the executive writes it (the check this test is about)
        genuine = RecordSubscription(g.node, schema)
        statuses: list[dict] = []
        RecordSubscription(g.node, c['traction_status'], callback=statuses.append)
        pub = foreign_publisher(g, schema.topic)

        def forged() -> bytes:
            fields = dict(genuine.fields or schema.decode(schema.encode()))
            # manual reverse: a REF the executive never sends, shown in traction's status
            fields.update(manual=1, manual_speed=20, reverse=1)
            counter = (genuine.raw[14] + 1) & 0xFF if genuine.raw else 0
            return schema.encode(fields, integrity='e2e', counter=counter)

        g.start_task(TASK)
        handshake(g, pub, 'traction', 'traction_command', forged())
        sent, speed = 1, g.speed
        # at the genuine stream's own 20 Hz, each with its next counter; paced so that
        # traction's reader queue (keep last 50) cannot overflow on a busy machine
        for _ in range(40):
            send(pub, forged())
            sent += 1
            spin_for(g, 0.05)
        error = completed_with_usual_stop(g)
        counted = counted_foreign(g, 'traction', 'traction_command', sent)
        # exactly ours, and nothing else: the genuine stream lost no record to a forged one
        assert counted == {'foreign_writer': sent}, counted
        assert statuses and not [s for s in statuses if s['manual'] or s['source'] == 'manual']
        held = held_for_the_graph(g)
        print(f'{sent} forged at {speed:.2f} m/s: {counted}; stop {error:+d} mm; '
              f'genuine records held for the graph at start-up: {held}')
        fault_table.add('foreign writer forging VALID traction_command records (right CRC, '
                        'next counter) while cruising',
                        'every one rejected as foreign_writer at traction, none acted on; '
                        'the task completes as usual',
                        f'{sent} forged: {sent} foreign_writer, no other rejection; completed, '
                        f'stop {error:+d} mm')
    finally:
        g.close()


def test_a_foreign_flood_of_bad_statuses_spends_no_rejection_budget(tmp_path,
                                                                          fault_table):
    schema = codec()['traction_status']
    g = GraphProbe(tmp_path / 'logs')
    try:
        pub = foreign_publisher(g, schema.topic)
        bad = bytes(16)  # CRC does not fit: E2E alone would charge it to the budget
        g.start_task(TASK)
        handshake(g, pub, 'executive', 'traction_status', bad)
        sent, start = 1, time.monotonic()
        # 2 every 50 ms for 5 s: 40 a second, 8 times reject_limit (5 a second), paced so
        # that the executive's reader queue (keep last 50) never overflows on a busy machine
        for _ in range(100):
            for _k in range(2):
                send(pub, bad)
                sent += 1
            spin_for(g, 0.05)
        rate = (sent - 1) / (time.monotonic() - start)
        error = completed_with_usual_stop(g)
        counted = counted_foreign(g, 'executive', 'traction_status', sent)
        assert counted == {'foreign_writer': sent}, counted
        # traction's start-up trip (before its first command) is the only one
        assert set(g.trips) <= {'startup'} and not g.errors, (set(g.trips), g.errors)
        print(f'{sent} bad traction_status at {rate:.0f}/s wall: {counted}; stop {error:+d} mm')
        fault_table.add('foreign writer flooding bad traction_status records (8 x the '
                        "executive's reject_limit a second) while cruising",
                        'every one rejected as foreign_writer, none charged to the rejection '
                        'budget; the task completes',
                        f'{sent} sent: {sent} foreign_writer; completed, stop {error:+d} mm')
    finally:
        g.close()


def test_a_driver_swap_names_the_writer_a_reader_takes(tmp_path, fault_table):
    import rclpy

    from agv_nodes.ros_ports import RecordPublisher, RecordSubscription

    c = codec()
    schema = c['traction_command']
    g = GraphProbe(tmp_path / 'logs',
                   extra={'traction': ["record_writers:=['traction_command=stand_in']"]})
    stand_in = rclpy.create_node('stand_in', context=g.context)
    try:
        statuses: list[dict] = []
        RecordSubscription(g.node, c['traction_status'], callback=statuses.append)
        pub = RecordPublisher(stand_in, schema)
        g.spin_until(lambda: g.launch.moving.is_set(), 120, 'the graph')
        g.spin_until(lambda: 'traction' in g.inputs and pub.subscription_count > 0, 60,
                     "traction's inputs row and the stand-in matched")
        # hand-shake: the stand-in's 00H (which also clears traction's trip latch) is taken
        deadline = time.monotonic() + 60
        while g.counted('traction', 'traction_command accepted') == 0:
            pub.publish({'demand': 0})
            spin_for(g, 0.05)
            assert time.monotonic() < deadline, g.inputs['traction']
        first = settled(g, lambda: g.counted('traction', 'traction_command accepted'),
                        "traction's count of the stand-in's hand-shake")
        for _ in range(40):  # 12 % with priority: a demand the executive at rest never sends
            pub.publish({'demand': 12, 'executive_priority': 1})
            spin_for(g, 0.05)
        g.spin_until(lambda: g.counted('traction', 'traction_command accepted') >= first + 40,
                     60, "traction counting the stand-in's commands")
        settled(g, lambda: g.counted('traction', 'traction_command accepted'), 'the count')
        row = g.inputs['traction']
        accepted = int(row['traction_command accepted'])
        assert accepted == first + 40, row
        foreign = reasons(g, 'traction', 'traction_command')
        assert set(foreign) == {'foreign_writer'} and foreign['foreign_writer'] > 20, row
        assert row['traction_command writer'].startswith('/stand_in ('), row
        assert 'from /executive' in row['traction_command last rejection'], row
        g.spin_until(lambda: any(s['ref'] == 12 for s in statuses), 30,
                     "traction's status showing the stand-in's demand")
        print(f'stand-in: {accepted} accepted; the executive: {foreign}')
        fault_table.add("driver swap: traction's record_writers names a stand-in for "
                        'traction_command',
                        "the stand-in's records accepted and acted on, the executive's "
                        'rejected as foreign_writer',
                        f'{accepted - first} of 40 accepted, REF 12 % shown; executive: '
                        f'{foreign["foreign_writer"]} foreign_writer')
    finally:
        stand_in.destroy_node()
        g.close()



def bool_publisher(g: GraphProbe, topic: str):
    """Return a writer of `topic` on the probe's own node (fault_probe: not the named writer)."""
    from std_msgs.msg import Bool

    from agv_nodes import qos

    return g.node.create_publisher(Bool, topic, qos.RECORD_WRITER)


@pytest.mark.timeout(420)
def test_a_foreign_radio_stop_stops_but_a_foreign_release_is_refused(tmp_path, fault_table):
    """hw/radio_stop's named writer is radio_receiver (settings.SWITCH_WRITERS).

    The probe's own node writes it too, and is foreign: its `true` stops the truck all the same
    (counted foreign_stop_taken), its `false` is refused (counted foreign_writer) and the radio
    stop holds until radio_receiver's `false`. traction_status's radio_stop flag is traction's
    radio input (PIO1-A bit 4), the world's inputs row counts what the world took.
    """
    from std_msgs.msg import Bool

    from agv_nodes.ros_ports import RecordSubscription

    c = codec()
    g = GraphProbe(tmp_path / 'logs')
    try:
        statuses: list[tuple[float, dict]] = []
        RecordSubscription(g.node, c['traction_status'],
                           callback=lambda f: statuses.append((g.time, f)))
        foreign = bool_publisher(g, 'hw/radio_stop')
        g.start_task(TASK)
        speed = g.speed
        g.spin_until(lambda: foreign.get_subscription_count() >= 2, 60,
                     'traction and the world matching the foreign radio stop')
        at = g.at_exact_time(lambda: foreign.publish(Bool(data=True)))
        g.spin_until(lambda: reasons(g, 'traction', 'radio_stop').get('foreign_stop_taken'),
                     60, 'traction counting the foreign stop')
        cut = g.drive_off_ms(at, 0.2)
        g.stays_at_rest()
        assert statuses[-1][1]['radio_stop'] == 1, statuses[-1]
        g.report_with('FAILED: radio stop (traction)')
        foreign.publish(Bool(data=False))  # the release, from the wrong writer
        g.spin_until(lambda: reasons(g, 'traction', 'radio_stop').get('foreign_writer'), 60,
                     'traction counting the foreign release')
        refused_at = g.time
        g.spin_until(lambda: g.time > refused_at + 2.0, 60, 'two sim seconds')
        held = [f['radio_stop'] for t, f in statuses if t >= refused_at - 0.5]
        assert held and set(held) == {1}, held  # never released
        g.spin_until(lambda: reasons(g, 'world', 'radio_stop') == {
            'foreign_stop_taken': 1, 'foreign_writer': 1}, 30, "the world's counts")
        g.radio_stop(False)  # radio_receiver: the named writer releases it
        g.spin_until(lambda: statuses[-1][1]['radio_stop'] == 0, 30,
                     "radio_receiver's release")
        counted = reasons(g, 'traction', 'radio_stop')
        assert counted == {'foreign_stop_taken': 1, 'foreign_writer': 1}, counted
        row = g.inputs['traction']
        assert '/fault_probe' in row['radio_stop last rejection'], row
        assert row['radio_stop writer'].startswith('/radio_receiver ('), row
        g.stays_at_rest(what='the truck to stay stopped after the release')
        print(f'foreign stop at {at:.2f} s, {speed:.2f} m/s: drive off {cut} ms; {counted}')
        fault_table.add('a foreign writer on hw/radio_stop: true while cruising, then false',
                        'its stop taken (fail-safe), its release refused; both counted and '
                        'named; only radio_receiver releases',
                        f'at {speed:.2f} m/s: drive off {cut} ms after; radio stop held '
                        f'2 s after the foreign false; traction {counted}')
    finally:
        g.close()
