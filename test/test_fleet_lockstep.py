"""Two 1983 trucks on one floor in lock step: shared stations, solid bodies, collisions reported.

agv_nodes.fleet.lockstep runs each truck's whole lock-step harness on demo_1983. Without traffic
control, two trucks sent to the same stop marker collide: the collision must be reported (world
event, the fleet's list, each truck's task FAILED with cause collision) and both must end at
rest, their drives cut by the bumper. Trucks kept apart never touch, and a load one truck takes
from a station is gone for the other.
"""

from __future__ import annotations

import math
import random

import pytest

from agv_nodes.fleet.lockstep import Fleet
from agv_nodes.world.contact import ContactWatch, footprint, overlap
from agv_nodes.world.layout import LayoutError
from agv_nodes.world.settings import WorldParams

pytestmark = pytest.mark.timeout(300)
AT_REST = 0.002  # m/s
SAMPLE = 1.0 / 340.0  # s, one world sample


def _at_rest(fleet: Fleet) -> bool:
    return all(abs(h.world.pose()[3]) < AT_REST for h in fleet.trucks.values())


def _events(fleet: Fleet, name: str, kind: str) -> list[dict]:
    return [e for e in fleet.trucks[name].events if e['event'] == kind]


def test_two_trucks_sent_to_one_stop_marker_collide_and_both_stop_reported(fault_table):
    fleet = Fleet('demo_1983', [('A', 4.0), ('A', 1.0)])  # agv2 3 m behind agv1
    for name in fleet.names:
        fleet.submit(name, 'stop at 2 first')
    fleet.run(60.0, until=lambda: bool(fleet.collisions) and _at_rest(fleet))
    (hit,) = fleet.collisions  # once, not once per sample of contact
    assert hit.trucks == ('agv1', 'agv2')
    assert hit.speeds[1] > 0.5  # agv2 at cruise ran into agv1 slowing for W2.1
    for name in fleet.names:
        (event,) = _events(fleet, name, 'collision')
        assert event['time'] == pytest.approx(hit.time)
        # the bumper cut the drive within the sample that found the contact
        off = [e['time'] for e in _events(fleet, name, 'drive_off') if e['time'] >= hit.time]
        assert off and off[0] - hit.time <= SAMPLE + 1e-9, (name, off)
    fleet.run(2.0)
    assert _at_rest(fleet)
    for name in fleet.names:
        assert any('FAILED: collision (traction)' in r for r in fleet.reports(name)), \
            fleet.reports(name)[-3:]
        world = fleet.trucks[name].world
        assert world.bumper
        world.hardware_reset()  # the reset frees the bumper
        assert not world.bumper
    fault_table.add('two trucks meet (no traffic control; lock step, demo_1983)',
                    'a collision event on both, drive cut by the bumper within one sample, '
                    'both at rest, each task FAILED: collision (traction)',
                    f'agv2 at {hit.speeds[1]:.2f} m/s ran into agv1 at {hit.speeds[0]:.2f} m/s; '
                    'both drives off in the same sample, both at rest, both tasks FAILED')


def test_trucks_kept_apart_share_the_stations_loads_and_never_touch():
    fleet = Fleet('demo_1983', [('A', 4.0), ('A', 1.0)])
    assert fleet.station_loads == {'W0': 1, 'W1': 1, 'W2': 0, 'W3': 0}
    fleet.submit('agv1', 'load at 0')
    fleet.submit('agv1', 'unload at 2')
    done = fleet.run(120.0, until=lambda: sum('completed' in r
                                              for r in fleet.reports('agv1')) == 2)
    assert done, fleet.reports('agv1')[-3:]
    assert fleet.station_loads == {'W0': 0, 'W1': 1, 'W2': 1, 'W3': 0}
    # agv2 to W0, where agv1 took the only load: the floor is one, the station is empty
    fleet.submit('agv2', 'load at 0')
    failed = fleet.run(120.0, until=lambda: any('FAILED' in r for r in fleet.reports('agv2')))
    assert failed, fleet.reports('agv2')[-3:]
    assert 'load failed' in fleet.reports('agv2')[-1]
    fleet.run(2.0)
    assert fleet.collisions == [] and _at_rest(fleet)
    for name in fleet.names:
        assert not _events(fleet, name, 'collision')


def test_a_fleet_refuses_trucks_that_touch_at_the_start_and_a_camera_floor():
    with pytest.raises(ValueError, match='touch at the start'):
        Fleet('demo_1983', [('A', 4.0), ('A', 3.0)])  # 1 m apart: bodies 1.8 m long
    with pytest.raises(LayoutError, match='wire layout'):
        Fleet('tape_1991', [('T', 1.0)])
    with pytest.raises(ValueError, match='2 starts for 1 trucks'):
        Fleet('demo_1983', [('A', 4.0), ('A', 1.0)], names=['x'])


@pytest.mark.parametrize('b, touching', [
    ((1.0, 0.0, 0.0), True),   # one behind the other, 0.8 m into it
    ((1.8, 0.0, 0.0), True),   # nose touches tail exactly (bodies 1.8 m long)
    ((1.81, 0.0, 0.0), False),
    ((0.0, 0.91, 0.0), False),  # side by side, 1 cm apart (0.9 m wide)
    ((0.0, 0.9, 0.0), True),
    ((0.6, 0.0, math.pi / 2), True),  # across its middle
    ((2.4, 1.1, math.pi / 4), False),  # a corner near, not in
])
def test_footprints_overlap_as_the_bodies_do(b, touching):
    p = WorldParams().electruk  # 1.2 m wheelbase, 0.3 m overhangs, 0.9 m wide
    a = footprint(0.0, 0.0, 0.0, p)
    assert overlap(a, footprint(*b, p)) is touching
    assert overlap(footprint(*b, p), a) is touching


def test_the_watch_finds_every_pair_the_edges_find():
    """The circles about the footprints only skip pairs that cannot touch (nose to tail too)."""
    p = WorldParams().electruk
    rng = random.Random(7)
    names = ['a', 'b', 'c', 'd']
    watch, touched = ContactWatch(names), 0
    for _ in range(2000):
        poses = {n: (rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-math.pi, math.pi), 0.0)
                 for n in names}
        poses['b'] = (1.8, 0.0, 0.0, 0.0)  # nose to tail with 'a' at the origin, exactly
        poses['a'] = (0.0, 0.0, 0.0, 0.0)
        shapes = {n: footprint(*poses[n][:3], p) for n in names}
        want = {(x, y) for i, x in enumerate(names) for y in names[i + 1:]
                if overlap(shapes[x], shapes[y])}
        got = watch.contacts({n: (poses[n], p) for n in names})
        assert got == want
        touched += len(got)
    assert touched > 2000  # every draw has a-b touching, and many others
