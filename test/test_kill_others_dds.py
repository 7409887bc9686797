"""The world, the recorder and a respawned node killed over DDS, and what each leaves behind.

test_kill_dds.py kills or freezes each of the seven truck nodes while it cruises; this file
the processes around them, one at a time, each on the whole graph (config/graph.yaml):

- load_handling killed during a load transfer, the truck at rest at W0: the conveyors'
  watchdog (world conveyor_timeout) stops them, so the load stays where it was.
- the world (the hardware) killed: sim time stops with its /clock, and with it every node's
  sim-time timers, /diagnostics included; each node's wall-clock watch (agv_nodes/clock_watch.py)
  reports the clock lost and names the hardware inputs it no longer gets.
- the recorder killed: the bag it leaves is readable up to the last second
  (recorder.CommittedFile), checked against what a probe subscriber saw.
- agv-launch --respawn: a killed node comes back and rejoins, and the truck stays stopped
  until a new task.
"""

from __future__ import annotations

import math
import signal
import statistics
import time

from graph_probe import CRUISE, STOP_TOLERANCE_MM, GraphProbe
import pytest
from test_kill_dds import silence_bound

pytestmark = [pytest.mark.dds, pytest.mark.slow]

DRIVE_OFF_WITHIN = 0.200  # simulated s from the kill to the drive no longer pushing
CLOCK_LOST_WITHIN = 10.0  # wall s from the world's death to every node naming it (2 s + load)


@pytest.mark.timeout(150)  # ~11 s alone
def test_load_handling_killed_during_a_transfer(tmp_path, fault_table):
    """W0 holds a load; the truck stops at L0 and its first conveyor runs: then the kill."""
    from agv_nodes.records.codec import codec
    from agv_nodes.ros_ports import RecordSubscription

    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add('load_handling')
    proc = g.launch.procs
    conveyor: dict[str, object] = {}
    RecordSubscription(g.node, codec()['conveyor_command'], 'e2e', conveyor.update)
    try:
        g.start_task('load at 0', cruise=None)
        g.spin_until(lambda: conveyor.get('first') == 'load', 120, 'the conveyor to run')
        g.spin_until(lambda: g.speed <= 0.005, 10, 'the truck at rest')
        started = g.time
        g.spin_until(lambda: g.time > started + 1.0, 30, '1 s of the transfer')
        killed_at = g.at_exact_time(lambda: proc['load_handling'].send_signal(signal.SIGKILL))
        g.spin_until(lambda: 'stale status (load)' in g.errors.get('executive', ''), 30,
                     f'/diagnostics naming load; have {g.errors}')
        g.report_with('FAILED: stale status (load)')
        g.stays_at_rest(hold=3.0)
        moved = [t - killed_at for t, e in g.events if e['event'] == 'load_moved']
        print(f'load_handling SIGKILL {killed_at - started:.2f} s into the transfer: '
              f'reports {g.reports}; load_moved {moved}; travelled '
              f'{g.travelled_since(killed_at):.3f} m')
        assert g.travelled_since(killed_at) < 0.01
        # the conveyors' own watchdog (world conveyor_timeout) stops the half-done transfer
        assert not moved, f'the conveyor ran on: load_moved {moved} s after the kill'
        fault_table.add('SIGKILL load_handling during a load transfer (truck at rest at W0)',
                        '"stale status (load)" reported and in /diagnostics, truck stays at '
                        'rest, the conveyors stop (no load moves)',
                        'as expected; 3 s after the kill no load had moved')
    finally:
        g.close()


@pytest.mark.timeout(180)  # ~8 s alone (SIGSTOP: ~20 s)
@pytest.mark.parametrize('sig', [signal.SIGKILL, signal.SIGSTOP], ids=['kill', 'stop'])
def test_world_gone_every_node_names_its_lost_inputs(tmp_path, sig, fault_table):
    """Killed or frozen, the world stops sim time; frozen and woken, the run carries on."""
    from agv_nodes.records.codec import codec

    g = GraphProbe(tmp_path / 'logs')
    g.expected_dead.add('world')
    nodes = [s.name for s in g.launch.specs() if s.role == 'node']
    lost = {n: sorted(s.name for s in codec() if s.writer == 'world' and n in s.readers)
            for n in nodes}
    world = g.launch.procs['world']
    try:
        g.start_task('stop at 2 second')
        world.send_signal(sig)
        killed = time.monotonic()
        g.errors.clear()

        def named() -> list[str]:
            return [n for n in nodes if 'clock lost' in g.errors.get(f'{n}/inputs', '')
                    and all(r in g.errors[f'{n}/inputs'] for r in lost[n])]
        g.spin_until(lambda: len(named()) == len(nodes), 60,
                     f'every node to name its lost inputs; have {g.errors}')
        took = time.monotonic() - killed
        print(f'world {sig.name}: all named after {took:.1f} s wall: ' + '\n'.join(
            f'{n}: {g.errors[n + "/inputs"]}' for n in nodes))
        assert took <= CLOCK_LOST_WITHIN, f'named only {took:.1f} s after the kill'
        outcome = ''
        if sig == signal.SIGSTOP:  # the hardware back: time runs on, nothing was missed
            frozen_at = g.time
            world.send_signal(signal.SIGCONT)
            g.spin_until(lambda: g.time > frozen_at + 0.5, 60, 'sim time to run again')
            g.report_with('completed', wall_limit=120)
            assert set(g.trips) <= {'startup'} and not any('FAILED' in r for r in g.reports), (
                g.trips, g.reports)
            stops = [e['error'] for _, e in g.events if e['event'] == 'stopped']
            assert stops and abs(stops[-1]) <= STOP_TOLERANCE_MM, stops
            outcome = f'; after SIGCONT the task completed, stop {stops[-1]:+d} mm'
        fault_table.add(f'{sig.name} world (hardware gone, sim time stops)',
                        f'every node: /diagnostics ERROR "clock lost" naming its hardware '
                        f'inputs within {CLOCK_LOST_WITHIN:.0f} s wall' + (
                            '; woken (SIGCONT): the task completes, no fault'
                            if sig == signal.SIGSTOP else ''),
                        f'all {len(nodes)} nodes after {took:.1f} s wall, e.g. route_following: '
                        f'{", ".join(lost["route_following"])}{outcome}')
    finally:
        if sig == signal.SIGSTOP and world.poll() is None:
            world.send_signal(signal.SIGCONT)  # so that it can shut down
        g.close()


@pytest.mark.timeout(120)  # ~20 s alone
def test_killed_recorder_leaves_a_bag_readable_to_its_last_second(tmp_path, fault_table):
    """What a probe saw more than 1 s (wall) before the kill is in the bag, read with rosbags.

    The recorder commits its bag twice a second of wall time (recorder.CHECKPOINT), so the
    claim is about wall time, for a recorder that keeps up with what it records. The run goes
    at half real time: at full speed the graph takes most of two cores, and a recorder starved
    of CPU falls behind by however much the machine lacks, which says nothing of its commits.
    """
    from rosbags.highlevel import AnyReader
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos
    from agv_nodes.ros_ports import clock_time_ns

    bag = tmp_path / 'bag'
    time_factor = 0.5
    lost_at_most = 1.0  # s of wall time before the kill
    g = GraphProbe(tmp_path / 'logs', bag=bag, time_factor=time_factor)
    g.expected_dead.add('recorder')
    topics = ['/clock', '/hw/position_sensor/adc', '/hw/wheel_odometry', '/navigation/status',
              '/traction/command', '/comms/command']
    seen: dict[str, list[float]] = {t: [] for t in topics[1:]}  # the probe's /clock at each
    clock = {'now': 0.0}
    clocks: list[int] = []

    def on_clock(raw: bytes) -> None:
        clocks.append(clock_time_ns(raw))
        clock['now'] = clocks[-1] * 1e-9

    # subscribed before the world moves (it waits for the graph's nodes), as the recorder is
    g.node.create_subscription(Clock, '/clock', on_clock, qos.CLOCK_READER, raw=True)
    for t in topics[1:]:
        g.node.create_subscription(UInt8MultiArray, t,
                                   lambda raw, t=t: seen[t].append(clock['now']),
                                   qos.RECORD_READER, raw=True)
    try:
        g.start_task('stop at 2 second', cruise=None)
        start = g.time
        g.spin_until(lambda: g.time > start + 3.0, 60, '3 s of the run (6 s wall)')
        g.launch.procs['recorder'].send_signal(signal.SIGKILL)
        kill = clock['now']
        limit = kill - lost_at_most * time_factor
        print(f'recorder SIGKILL at {kill:.3f} s sim')
        by_topic: dict[str, list[int]] = {t: [] for t in topics}
        with AnyReader([bag]) as reader:
            for conn, stamp, _raw in reader.messages():
                if conn.topic in by_topic:
                    by_topic[conn.topic].append(stamp)
        bag_clock = {int(c) for c in by_topic['/clock']}
        lost_clock = [c for c in clocks if c * 1e-9 <= limit and c not in bag_clock]
        assert not lost_clock, f'{len(lost_clock)} /clock samples before {limit:.3f} s lost'
        counts = {}
        for t in topics[1:]:
            # the probe stamps a record on the /clock it had, the bag on its send: 0.1 s apart
            probe = sum(1 for s in seen[t] if s <= limit - 0.1 * time_factor)
            in_bag = sum(1 for s in by_topic[t] if s * 1e-9 <= limit)
            counts[t] = (probe, in_bag)
            assert probe > 0 and in_bag >= probe, f'{t}: probe {probe}, bag {in_bag}'
        last = max(by_topic['/clock']) * 1e-9
        print(f'bag: last /clock {last:.3f} s ({kill - last:.2f} s sim before the kill); '
              f'(probe, bag) up to {limit:.3f} s: {counts}')
        fault_table.add('SIGKILL recorder during a run (half real time)',
                        'the bag reads (rosbags AnyReader) and holds everything the probe saw '
                        f'more than {lost_at_most:g} s (wall) before the kill',
                        f'bag readable, ends {(kill - last) / time_factor:.2f} s (wall) before '
                        f'the kill; nothing older than {lost_at_most:g} s missing '
                        f'({sum(p for p, _ in counts.values())} records and '
                        f'{len([c for c in clocks if c * 1e-9 <= limit])} /clock checked)')
    finally:
        g.close()


@pytest.mark.timeout(150)  # ~20 s alone
def test_frozen_recorder_resumes_and_the_truck_never_notices(tmp_path, fault_table):
    """SIGSTOP the recorder for 3 s of a real-time run, then SIGCONT: nobody waits for it."""
    from rosbags.highlevel import AnyReader

    bag = tmp_path / 'bag'
    g = GraphProbe(tmp_path / 'logs', bag=bag, time_factor=1.0)  # sim s = wall s
    recorder = g.launch.procs['recorder']
    try:
        g.start_task('stop at 2 second')
        recorder.send_signal(signal.SIGSTOP)
        frozen = g.time
        g.spin_until(lambda: g.time > frozen + 3.0, 60, '3 s with the recorder frozen')
        recorder.send_signal(signal.SIGCONT)
        woken = g.time
        g.report_with("'stop at 2 second': completed", wall_limit=120)
        assert set(g.trips) <= {'startup'} and not any('FAILED' in r for r in g.reports), (
                g.trips, g.reports)
        g.spin_until(lambda: g.time > woken + 2.0, 60, '2 s after the recorder woke')
        ends = g.time
    finally:
        if recorder.poll() is None:
            recorder.send_signal(signal.SIGCONT)
        g.close()  # the recorder closes its bag
    with AnyReader([bag]) as reader:
        stamps = sorted(stamp * 1e-9 for conn, stamp, _ in reader.messages()
                        if conn.topic == '/clock')
    before = [t for t in stamps if t < frozen - 0.1]
    after = [t for t in stamps if woken + 0.5 < t < ends - 0.5]
    # what came before the freeze is there, and once it woke, every /clock step: no gap
    # wider than two steps
    assert before and frozen - before[-1] < 0.2, (frozen, before[-3:])
    gaps = [b - a for a, b in zip(after, after[1:], strict=False)]
    step = statistics.median(gaps)
    assert len(after) > 100 and max(gaps) <= 2.5 * step, (len(after), step, max(gaps))
    print(f'recorder frozen {frozen:.2f}-{woken:.2f} s: {len(before)} /clock before, '
          f'{len(after)} after, /clock step {step * 1000:.1f} ms, widest gap after '
          f'{max(gaps) * 1000:.1f} ms; reports {g.reports}')
    fault_table.add('SIGSTOP recorder for 3 s, then SIGCONT (real time)',
                    'the task completes with no fault; the bag, closed at the end, holds '
                    'the run before the freeze and every /clock step after it',
                    f'completed; {len(before)} /clock before the freeze, {len(after)} after '
                    f'the wake, no gap over {max(gaps) * 1000:.0f} ms')


@pytest.mark.timeout(180)  # ~13 s alone
def test_respawned_node_rejoins_and_the_truck_waits_for_a_new_task(tmp_path, fault_table):
    from agv_nodes.records.codec import codec
    from agv_nodes.ros_ports import RecordSubscription

    victim = 'navigation'
    g = GraphProbe(tmp_path / 'logs', respawn=True)
    g.expected_dead.add(victim)
    proc = g.launch.procs
    statuses: list[float] = []
    RecordSubscription(g.node, codec()['navigation_status'], 'e2e',
                       lambda _fields: statuses.append(g.time))
    sent = g.watch_sent('navigation_status')
    try:
        _least, worst, terms = silence_bound(g, victim)
        g.start_task('stop at 2 second')
        first = proc[victim]
        killed_at = g.at_exact_time(lambda: first.send_signal(signal.SIGKILL))
        at_rest = g.stays_at_rest() - killed_at
        last = g.last_sent_before(sent, killed_at)
        # the stale status's chain at worst (a respawn back in time is named sooner)
        limit = min(DRIVE_OFF_WITHIN, worst + last - killed_at)
        cut = g.drive_off_ms(killed_at, math.ceil(limit * 1000) / 1000)
        # The world waits up to lag_patience (real) for the dead node: a respawn back within
        # it finds sim time where it was killed, and the executive fails the task on the new
        # writer rather than on the silence. Either way it is navigation that failed.
        g.report_with('FAILED: ')
        failed = next(r for r in g.reports if 'FAILED: ' in r)
        assert any(f'FAILED: {cause} (navigation)' in failed
                   for cause in ('stale status', 'restarted')), g.reports
        g.spin_until(lambda: proc[victim] is not first, 30, f'{victim} to be respawned')
        back = g.time
        g.spin_until(lambda: sum(1 for t in statuses if t > back) >= 20, 60,
                     f'the respawned {victim} to send its status again')
        g.inputs.pop(victim, None)
        g.spin_until(lambda: victim in g.inputs, 30, f"the respawned {victim}'s inputs row")
        rejoined = g.time
        g.stays_at_rest(hold=5.0, what='the truck to stay stopped after the respawn')
        assert g.travelled_since(killed_at + at_rest) < 0.01
        reports = len(g.reports)
        g.task_pub.publish(_string('stop at 2 second'))
        g.spin_until(lambda: g.speed > CRUISE, 90, 'the truck to move on the new task')
        g.spin_until(lambda: any('completed' in r for r in g.reports[reports:]), 90,
                     'the new task to complete')
        print(f'{victim} SIGKILL at {killed_at:.2f} s: drive off {cut} ms, respawned, its '
              f'inputs row back {rejoined - back:.2f} s sim later; reports {g.reports}')
        fault_table.add(f'SIGKILL {victim} while cruising, agv-launch --respawn',
                        f'drive off <= {DRIVE_OFF_WITHIN:.3f} s (sim) after the kill and <= '
                        f'{worst * 1000:.1f} ms after its last navigation_status ({terms}), '
                        '"FAILED: stale status (navigation)" or "FAILED: restarted '
                        '(navigation)", the node respawns and '
                        'its records flow again, the truck moves only on a new task',
                        f'drive off after {cut / 1000:.3f} s, '
                        f'{(cut / 1000 + killed_at - last) * 1000:.1f} ms after its last '
                        f'navigation_status ({failed.split(": ", 1)[-1]}); '
                        'respawned, at rest 5 s after rejoining; the new task completed')
    finally:
        g.close()


def _string(text: str):
    from std_msgs.msg import String

    return String(data=text)
