"""Parking stops of the CONCIC-II: a leg with a length ends within 5 mm of it, both ways.

Rajagopalan 1991, 7.3.4 (Fig. 7.9): a motor-off stop from 0.16 m/s, "the recommended speed for
parking", takes 5 mm. A leg with a length slows to that speed and cuts the motors where the coast
ends at the length (route following's parking_speed, parking_distance; camera_mode.py).

Lock step, the whole camera truck (world, route following, executive, communications) on a
straight 12 m tape written for the test (and junction_1991 for a reverse leg that turns at its
cross), at the default speeds and on the default (dynamic) CONCIC-II model; each leg's length
is measured by the world's ground truth, the path of the axle centre from the leg's start to
rest, not by the truck's odometry.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from tape_floors import straight_tape

from agv_nodes.harness import Harness, submit, truck
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameters
from agv_nodes.world.settings import Concic2Params

LAYOUT = straight_tape('parking_1991', 'a straight tape, the truck 3 m along it', 12.0, 3.0)
CLAIM = 0.005  # m: the thesis's 5 mm stop from parking speed, the bound on each leg's end


def default(cls: type, name: str) -> float:
    """Return a parameter's declared default (the parameter files, not the code under test)."""
    return next(p.default for p in parameters(cls) if p.name == name)


def parking_truck(tmp_path: Path, **route: object) -> Harness:
    path = tmp_path / 'parking_1991.yaml'
    path.write_text(LAYOUT)
    # The rear camera rendered: the reverse leg's window leads.
    return truck(str(path), seed=4, overrides={'world': {'rear_camera': True},
                                               'route_following': route})


def run_legs(h: Harness, text: str, seconds: float = 60.0) -> tuple[list[float], list[float]]:
    """Run the task; return each leg's ground-truth travel (m) and the speed at its motor cut."""
    ex, s = h.cores['executive'], h.world.vehicle.state
    h.run(0.5)
    submit(h, text)
    travels: list[float] = []
    cuts: list[float] = []
    leg, last, enabled = None, (s.x, s.y), False
    end = h.now + seconds
    while h.now < end and ex.mode not in ('idle', 'failed') or not travels:
        h.step()
        if ex.tape.leg != leg:  # the executive's next leg: the last one's truck is at rest
            leg = ex.tape.leg
            travels.append(0.0)
        travels[-1] += math.dist(last, (s.x, s.y))
        last = (s.x, s.y)
        if enabled and not h.world.vehicle.enable:
            cuts.append(abs(s.speed))
        enabled = h.world.vehicle.enable
    assert ex.report['state'] == 'completed', ex.report
    return travels, cuts


@pytest.mark.timeout(240)
@pytest.mark.parametrize('forward, back', [(0.5, 1.5), (1.2, 0.4), (2.5, 2.0)])
def test_legs_end_within_5_mm_of_their_length_forwards_and_in_reverse(
        tmp_path: Path, forward: float, back: float) -> None:
    h = parking_truck(tmp_path)
    travels, cuts = run_legs(h, f'tape for {forward} m then reverse for {back} m')
    assert len(travels) == 2
    assert travels[0] == pytest.approx(forward, abs=CLAIM)
    assert travels[1] == pytest.approx(back, abs=CLAIM)
    # The motors are cut at parking speed (the wheels settle to it within 1 cm/s), not cruise.
    parking = default(RouteParams, 'parking_speed')
    assert len(cuts) == 2 and all(c < parking + 0.01 for c in cuts), cuts
    assert abs(h.world.vehicle.state.speed) < 1e-3


@pytest.mark.timeout(120)
def test_parking_speed_0_is_the_motor_off_stop_from_cruise(tmp_path: Path) -> None:
    """The old stop: the executive cuts the motors at the length, the truck coasting on.

    From cruise v a coast at the world's coast_deceleration a runs v^2 / 2a (42 mm from 0.47
    m/s at 2.6 m/s^2, the thesis's 5 mm from 0.16 m/s), far past the 5 mm claim; the executive
    cuts the motors once route_status's distance reaches the length, so never sooner.
    """
    h = parking_truck(tmp_path, parking_speed=0.0)
    travels, cuts = run_legs(h, 'tape for 1.5 m then reverse for 1 m')
    cruise = default(RouteParams, 'camera_speed')
    coast = cruise ** 2 / (2.0 * default(Concic2Params, 'coast_deceleration'))
    assert all(c == pytest.approx(cruise, abs=0.02) for c in cuts), cuts
    for travel, length in zip(travels, (1.5, 1.0), strict=True):
        assert travel - length > coast - CLAIM, (travels, coast)


@pytest.mark.timeout(120)
def test_a_dead_reckoning_leg_parks_at_its_length_too(tmp_path: Path) -> None:
    h = parking_truck(tmp_path)
    travels, _ = run_legs(h, 'reckon trajectory 1 for 1.5 m')
    assert travels == [pytest.approx(1.5, abs=CLAIM)]


@pytest.mark.timeout(300)
def test_a_reverse_leg_that_turns_at_a_junction_parks_at_its_length() -> None:
    """junction_1991: left at the R2, up the branch to its end, back down it and left of travel.

    The reverse leg's 4 m: 2.4-2.5 m back down the branch to the cross (the forward leg's
    window ran off the branch's end), the quarter turn over it (the axle centre stays put), then
    along the main tape toward +x, parking at 4 m of the axle's ground-truth travel. Counted as
    the sum of |travel|, the wheels' mean swinging back and forth in the spin (one wheel's loop
    lagging the other's) had the truck park 72 mm short.
    """
    h = truck('junction_1991', seed=4, overrides={'world': {'rear_camera': True}})
    travels, _cuts = run_legs(h, 'tape junctions 1 left, 2 left then reverse for 4 m', 150.0)
    assert len(travels) == 2 and travels[1] == pytest.approx(4.0, abs=CLAIM), travels
    s = h.world.vehicle.state
    assert abs(s.y) < 0.01 and s.x > 3.5, (s.x, s.y)  # on the main tape, past the cross
