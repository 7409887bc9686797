"""The world's C kernels give the bits of the Python code they stand in for.

`agv_nodes/world/_kernels.c` (built by `pip install -e .`, as the README installs the package)
steps the Electruk, sums the guide-wire field and runs the marker sensor's optics; `kernels:
python` runs the Python code. Both are driven here from the same states and poses, and a whole
truck's world in lock step is run both ways: every record it sends must be the same.
"""

from __future__ import annotations

import copy
import math
import random

import numpy as np
import pytest

from agv_nodes.harness import DEMO_PROGRAMME, submit, truck
from agv_nodes.world import kernels
from agv_nodes.world.guide_wire import SCALAR_SEGMENTS, GuideWirePickup
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.marker_sensor import MarkerSensorModel
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.vehicles import Electruk

pytestmark = pytest.mark.timeout(300)


def test_the_kernels_are_built_where_the_package_is_installed():
    assert kernels.compiled is not None, 'agv_nodes/world/_kernels.c was not built'
    assert kernels.select('auto') is kernels.compiled
    assert kernels.select('c') is kernels.compiled
    assert kernels.select('python') is None


def test_a_bad_choice_or_c_unbuilt_is_refused(monkeypatch):
    with pytest.raises(ValueError, match="'fortran' is not one of auto, c, python"):
        kernels.select('fortran')
    monkeypatch.setattr(kernels, 'compiled', None)
    assert kernels.select('auto') is None
    with pytest.raises(ValueError, match="'c' asks for the compiled kernels"):
        kernels.select('c')


def _truck_pair(rng: random.Random) -> tuple[Electruk, Electruk]:
    """Two Electruks in the same random state and with the same inputs: C and Python."""
    p = WorldParams().electruk
    pair = Electruk(p, kernels.compiled), Electruk(p, None)
    state = rng.getstate()
    for t in pair:
        rng.setstate(state)
        t.state.speed = rng.uniform(-1.2, 1.2) if rng.random() < 0.8 else 0.0
        t.state.heading = rng.uniform(-math.pi, math.pi)
        t.state.x, t.state.y = rng.uniform(-50, 50), rng.uniform(-50, 50)
        t.flux, t.current = rng.uniform(-1, 1), rng.uniform(0, 120)
        t.steer = rng.uniform(-0.6, 0.6) if rng.random() < 0.8 else 0.0
        t.set_drive(rng.uniform(0, 0.8), rng.uniform(0, 1), rng.random() < 0.5,
                    rng.random() < 0.8, rng.random() < 0.8, rng.random() < 0.9)
        t.steer_enable, t.steer_demand = rng.random() < 0.8, rng.uniform(-1, 1)
        t.relay_closed, t.radio_stop = rng.random() < 0.9, rng.random() < 0.1
    return pair


def test_the_electruk_steps_to_the_same_bits_in_c_and_in_python():
    rng = random.Random(7)
    for _ in range(1500):
        c, py = _truck_pair(rng)
        for _ in range(25):
            for t in (c, py):
                t.step(1 / 1360, 4)
        assert (vars(c.state), c.flux, c.current, c.steer) == \
            (vars(py.state), py.flux, py.current, py.steer)


@pytest.mark.parametrize('name', ['demo_1983', 'fleet_1983', 'straight_track'])
def test_the_pickup_reads_the_same_bits_in_c_and_in_python(name):
    lay = load_layout(layout_path(name))
    wires = [w for w in lay.paths.values() if w.width == 0.0]
    if not wires:
        pytest.fail(f'{name} has no wire to test on')
    p = WorldParams().pickup
    c = GuideWirePickup(p, wires, random.Random(1), kernels.compiled)
    py = GuideWirePickup(p, wires, random.Random(1), None)
    rng = random.Random(2)
    paths = {'scalar': 0, 'pairwise': 0}
    for w in wires:
        for at in np.linspace(0.0, w.length, 2500):
            x, y, heading = (float(v) for v in w.pose_at(at))
            off = rng.uniform(-0.4, 0.4)
            x, y = x - math.sin(heading) * off, y + math.cos(heading) * off
            heading += rng.uniform(-0.3, 0.3)
            assert c.coils(x, y, heading) == py.coils(x, y, heading)
            # the field itself, before rounding to counts, on both of Python's paths
            lx, ly = -math.sin(heading), math.cos(heading)
            half = p.coil_spacing / 2.0
            points = ((x + half * lx, y + half * ly), (x - half * lx, y - half * ly))
            scalar = len(py._near) <= SCALAR_SEGMENTS
            paths['scalar' if scalar else 'pairwise'] += 1
            want = (py._lateral_scalar if scalar else py._lateral_numpy)(points, x, y, lx, ly)
            (p0x, p0y), (p1x, p1y) = points
            got = kernels.compiled.wire_lateral(py._near_table, x, y, lx, ly, p0x, p0y, p1x, p1y,
                                                p.coil_height, p.reach, scalar)
            assert list(got) == list(want)
    assert paths['scalar'] > 100
    if name != 'straight_track':
        assert paths['pairwise'] > 100  # arcs of many short segments: numpy's pairwise sums


@pytest.mark.parametrize('name', ['demo_1983', 'fleet_1983', 'sensor_rig'])
def test_the_optics_see_the_same_bits_in_c_and_in_python(name):
    """Lens poses about every card of the floor: near, far, turned, raised; each detector."""
    lay = load_layout(layout_path(name))
    cards = [m for m in lay.markers]
    p = WorldParams().sensor
    c = MarkerSensorModel(p, random.Random(1), kernels.compiled)
    py = MarkerSensorModel(p, random.Random(1), None)
    rng = random.Random(5)
    seen = 0
    for card in cards:
        nx, ny = card.normal
        for _ in range(300):
            standoff = rng.uniform(0.15, 0.7)
            along = rng.uniform(-0.4, 0.4)
            lens = (card.centre[0] + nx * standoff - ny * along,
                    card.centre[1] + ny * standoff + nx * along)
            heading = math.atan2(-nx, ny) + rng.uniform(-0.5, 0.5)  # axis on the card
            height = rng.choice((0.0, rng.uniform(-0.02, 0.03)))
            near = rng.sample(cards, min(3, len(cards))) + [card]
            want = py._look(lens, heading, near, height)
            assert c._look(lens, heading, near, height) == want, (name, card, lens, heading)
            seen += bool(want)
    assert seen > 100  # poses where a detector sees a card


def test_a_whole_truck_sends_the_same_records_with_either_kernels():
    """The first 60 s of the demonstration programme, every record byte compared."""
    sent = {}
    for choice in ('c', 'python'):
        h = truck('demo_1983', seed=3, overrides={'world': {'kernels': choice}})
        assert (h.world.vehicle._step_kernel is None) == (choice == 'python')
        tape: list[tuple[str, bytes]] = []
        h.taps.append(lambda record, raw, now, tape=tape: tape.append((record, raw)))
        for text in DEMO_PROGRAMME:
            submit(h, text)
        h.run(60.0)
        sent[choice] = tape
    assert len(sent['c']) > 50_000
    assert sent['c'] == sent['python']


def test_a_world_with_its_kernels_deep_copies_and_the_copy_runs_on_alike():
    """Tests fork a truck's state with copy.deepcopy: the kernels travel with it."""
    h = truck('demo_1983', seed=4)
    submit(h, DEMO_PROGRAMME[0])
    h.run(5.0)
    twin = copy.deepcopy(h)
    assert twin.world.vehicle._step_kernel is kernels.compiled.electruk_step
    for harness in (h, twin):
        harness.run(5.0)
    assert vars(twin.world.vehicle.state) == vars(h.world.vehicle.state)
