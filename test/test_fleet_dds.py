"""Several trucks on one floor over DDS (agv-launch --trucks N).

Each truck's whole graph runs in its own namespace; one world process simulates them all on
one clock, and their bodies collide.
"""

from __future__ import annotations

from fleet_probe import FleetProbe
import pytest

pytestmark = [pytest.mark.dds, pytest.mark.timeout(420)]

AT_REST = 0.005  # m/s


@pytest.fixture
def fleet(tmp_path):
    probes: list[FleetProbe] = []

    def start(trucks: int, **options) -> FleetProbe:
        probes.append(FleetProbe(tmp_path / 'logs', trucks, **options))
        return probes[-1]

    yield start
    for probe in probes:
        probe.close()


def collisions(truck) -> list[dict]:
    return [e for e in truck.events if e['event'] == 'collision']


def test_two_trucks_each_run_their_own_task_on_one_floor_and_never_touch(fleet):
    """agv1 set down at W2.2 runs on to W1.1; agv2, behind it at W0.1, follows to W2.2."""
    probe = fleet(2)
    probe.ready()
    a, b = probe.trucks['agv1'], probe.trucks['agv2']
    a.send('stop at 1')
    probe.spin_until(lambda: a.speed > 0.3, 120, 'agv1 to leave W2.2')
    b.send('stop at 2 second')
    probe.spin_until(lambda: a.finished() and b.finished(), 300, 'both tasks to end')
    assert any("'stop at 1': completed" in r for r in a.reports), a.reports
    assert any("'stop at 2 second': completed" in r for r in b.reports), b.reports
    assert not collisions(a) and not collisions(b)
    assert a.moved > 10.0 and b.moved > 3.5  # W2.2 -> W1.1 is ~12 m; W0.1 -> W2.2 4.2 m
    assert not [line for line in probe.launch.lines if 'collision' in line]


def test_a_truck_driven_into_another_collides_and_both_drives_are_cut(fleet):
    """agv2 at W0.1 is sent past agv1, which stands at W2.2: they touch, and both stop."""
    probe = fleet(2)
    probe.ready()
    a, b = probe.trucks['agv1'], probe.trucks['agv2']
    b.send('stop at 1')
    probe.spin_until(lambda: collisions(a) and collisions(b), 120, 'a collision event on both')
    probe.spin_until(lambda: b.finished(), 60, "agv2's task to end")
    assert any("'stop at 1': FAILED: collision" in r for r in b.reports), b.reports
    t0 = b.time
    probe.spin_until(lambda: b.time > t0 + 2.0, 60, '2 s more')
    assert b.speed < AT_REST and a.speed < AT_REST
    assert any('collision at' in line and 'agv1' in line and 'agv2' in line
               for line in probe.launch.lines), 'the floor logs the collision'


@pytest.mark.timeout(900)
def test_the_quick_fleet_demo_runs_two_transfers_over_mqtt_without_a_collision(tmp_path):
    """`agv-demo --fleet 2 --quick`: the dispatcher drives both trucks' bridges over MQTT."""
    import json

    from rosbags.highlevel import AnyReader
    from test_graph_dds import node_warnings, run_demo

    res = run_demo(tmp_path, '--fleet', '2', '--quick', timeout=780)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:] + node_warnings(tmp_path)
    summary = json.loads((tmp_path / 'fleet.json').read_text())
    assert sorted(t['id'] for t in summary['done']) == ['t1', 't2'], summary['done']
    assert summary['failed'] == [] and summary['collisions'] == 0
    assert all(metres > 10.0 for metres in summary['distance_m'].values())
    # 2 x (7 nodes + bridge) + world, recorder, dispatcher
    assert summary['processes'] == 19
    with AnyReader([tmp_path / 'bag']) as bag:
        topics = set(bag.topics)
    assert {'/agv1/world/pose', '/agv2/world/pose', '/fleet/report', '/fleet/transport',
            '/agv1/comms/report', '/agv2/comms/report', '/clock'} <= topics
