"""World core: physics checks with numbers, layouts, determinism, safety inputs, camera truth."""

from __future__ import annotations

import dataclasses
import math
import random

import numpy as np
import pytest

from agv_nodes.harness import Harness
from agv_nodes.markers import (
    LOCATION_PATTERNS,
    SNAPSHOT_FIELDS,
    THRESHOLDS,
    code_of,
    snapshot_record,
    stop_view_columns,
)
from agv_nodes.world.camera import BinaryCamera
from agv_nodes.world.core import WorldCore
from agv_nodes.world.guide_wire import SCALAR_SEGMENTS
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.marker_sensor import MarkerSensorModel, _belt_runs, calibrate
from agv_nodes.world.settings import CameraParams, ElectrukParams, SensorParams, WorldParams
from agv_nodes.world.vehicles import Electruk


def layout(name: str):
    return load_layout(layout_path(name))


class ScriptedDrive:
    """A test core standing in for traction + route following: fixed drive, steering held."""

    node = 'test_drive'
    period = 0.01

    def __init__(self, duty: int = 60, angle: int = 0) -> None:
        self.duty, self.angle, self.contactor, self.watchdog_running = duty, angle, 1, True
        self.count = 0

    def on_record(self, record, fields, now):
        return None

    def tick(self, now):
        if self.watchdog_running:
            self.count = (self.count + 1) & 0xFF
        return {'traction_drive': dict(armature_duty=self.duty, field_duty=98,
                                       armature_enable=int(self.duty > 0), field_enable=1,
                                       field_forward=1, contactor=self.contactor,
                                       watchdog=self.count),
                'steering_command': dict(mode='angle', enable=1, angle=self.angle,
                                         left_speed=0, right_speed=0)}


@pytest.fixture
def drive_codec():
    """Return the installed schemas plus a writer entry for the scripted test core."""
    from agv_nodes.records import codec
    from agv_nodes.records.codec import Codec

    c = codec()
    schemas = []
    for s in c:
        if s.name in ('traction_drive', 'steering_command'):
            s = dataclasses.replace(s, writer='test_drive')
        schemas.append(s)
    return Codec(schemas)


def threshold(lit, dark, unit='sensor1'):
    """Test oracle: Baker 1983, 5.2.3's THRESH on a steady snapshot (sum of 4 equal)."""
    t = THRESHOLDS[unit]
    code = 0
    for d in range(8):
        total = 4 * max(lit[d] - dark[d], 0)
        if total > t['white'][d]:
            code = code << 1 | 1
        elif total <= t['black'][d]:
            code <<= 1
        else:
            return None
    return code


# -- marker sensor physics -----------------------------------------------------------------
@pytest.mark.parametrize('identity', [0, 1, 2, 3])
@pytest.mark.parametrize('standoff', [0.280, 0.300, 0.320])
def test_snapshot_centred_on_location_marker_gives_its_template(identity, standoff):
    lay = layout('straight_track')
    card = next(m for m in lay.markers if m.kind == 'location' and m.identity == identity)
    model = MarkerSensorModel(SensorParams(), random.Random(identity))
    x, y = card.centre
    lens = (x, y + standoff)  # the card faces +y (toward the wire), the lens looks -y
    lit, dark = model.snapshot(lens, 0.0, lay.markers)
    assert threshold(lit, dark) == code_of(LOCATION_PATTERNS[identity])


@pytest.mark.parametrize('view', range(1, 8))
def test_stop_marker_views_and_distance_to_go(view):
    """View k is aligned when the lens is (60 - 20 (k-1)) mm short of the card centre."""
    lay = layout('straight_track')
    card = next(m for m in lay.markers if m.kind == 'stop')
    model = MarkerSensorModel(SensorParams(noise=0.0, ambient_noise=0.0), random.Random(0))
    to_go = (60 - 20 * (view - 1)) / 1000
    lens = (card.centre[0] - to_go, card.centre[1] + 0.300)
    lit, dark = model.snapshot(lens, 0.0, lay.markers)
    assert threshold(lit, dark) == code_of(card.rows, stop_view_columns(view))


def test_between_alignments_the_snapshot_is_invalid():
    lay = layout('straight_track')
    card = next(m for m in lay.markers if m.kind == 'location' and m.identity == 2)
    model = MarkerSensorModel(SensorParams(noise=0.0, ambient_noise=0.0), random.Random(0))
    lit, dark = model.snapshot((card.centre[0] + 0.010, card.centre[1] + 0.3), 0.0, lay.markers)
    assert threshold(lit, dark) is None  # half an element off: detectors in their bands


def test_calibration_reproduces_table_7_1():
    """The simulated threshold experiment gives back Baker 1983, Table 7.1's worst-case levels."""
    params = SensorParams()
    gains, blacks = calibrate(params)
    assert all(g > 0 for g in gains) and all(0 <= b < 0.5 for b in blacks)
    key = tuple(sorted((k, v) for k, v in vars(params).items()
                       if k not in ('gains', 'blacks', 'unit', 'noise', 'ambient',
                                    'ambient_noise', 'dark_level')))
    runs = _belt_runs(key)
    from agv_nodes.markers import trough_and_peak

    for d, (trough, peak) in enumerate(trough_and_peak('sensor1')):
        a, b = gains[d] * blacks[d], gains[d]
        worst_peak = min(a * r[d][0][0] + b * r[d][0][1] for r in runs)
        worst_trough = max(a * r[d][1][0] + b * r[d][1][1] for r in runs)
        assert worst_peak == pytest.approx(peak, rel=1e-6)
        if blacks[d] > 0:
            assert worst_trough == pytest.approx(trough, rel=1e-6)
        white = THRESHOLDS['sensor1']['white'][d]
        black = THRESHOLDS['sensor1']['black'][d]
        assert worst_trough < black < white < worst_peak


def test_ambient_light_cancels_until_the_adc_saturates():
    lay = layout('straight_track')
    card = lay.markers[0]
    lens = (card.centre[0], card.centre[1] + 0.3)
    clean = MarkerSensorModel(SensorParams(noise=0, ambient_noise=0), random.Random(0))
    sunny = MarkerSensorModel(SensorParams(noise=0, ambient_noise=0, ambient=60),
                              random.Random(0))
    blind = MarkerSensorModel(SensorParams(noise=0, ambient_noise=0, ambient=300),
                              random.Random(0))
    a = clean.snapshot(lens, 0.0, lay.markers)
    b = sunny.snapshot(lens, 0.0, lay.markers)
    assert [x - y for x, y in zip(*a, strict=True)] == [x - y for x, y in zip(*b, strict=True)]
    lit, dark = blind.snapshot(lens, 0.0, lay.markers)
    assert lit == dark == [255] * 8  # blinded: no on/off difference left


# -- truck --------------------------------------------------------------------------------
def run_truck(duty: float, seconds: float, payload: float = 0.0) -> Electruk:
    truck = Electruk(ElectrukParams(payload=payload))
    truck.set_drive(duty, 0.98, True, True, True, True)
    dt = 1 / 1360
    for _ in range(int(seconds / dt)):
        truck.step(dt)
    return truck


def test_80_percent_duty_gives_about_1_m_per_s_unloaded():
    assert 0.95 <= run_truck(0.80, 10).state.speed <= 1.05  # Baker 1983, 6.3.2: 80 % ~ 1 m/s
    assert 0.17 <= run_truck(0.20, 10).state.speed <= 0.23  # 20 % ~ 0.2 m/s
    assert run_truck(0.05, 10).state.speed == 0.0  # nothing moves below ~5 %


def test_cutting_drive_at_0_7_m_per_s_stops_in_a_friction_distance():
    truck = run_truck(0.60, 10)
    v0 = truck.state.speed
    assert 0.65 <= v0 <= 0.78
    x0 = truck.state.distance
    truck.set_drive(0.0, 0.98, True, False, True, True)
    while truck.state.speed > 0:
        truck.step(1 / 1360)
    coast = truck.state.distance - x0
    assert 0.3 <= coast <= 1.0  # friction only; Baker 1983 needed 1 m marker spacing at 0.7
    assert truck.state.speed == 0.0


def test_plug_braking_stops_shorter_than_friction():
    def stop_distance(field_forward: bool) -> float:
        truck = run_truck(0.20, 8)
        x0 = truck.state.distance
        truck.set_drive(0.05, 0.98, field_forward, not field_forward, True, True)
        for _ in range(1360 * 3):
            truck.step(1 / 1360)
            if truck.state.speed <= 0:
                break
        return truck.state.distance - x0

    assert stop_distance(False) < stop_distance(True)


def test_contactor_open_or_radio_stop_means_no_drive_torque():
    for cut in ('contactor', 'radio'):
        truck = run_truck(0.5, 5)
        truck.set_drive(0.5, 0.98, True, True, True, cut != 'contactor')
        truck.radio_stop = cut == 'radio'
        for _ in range(1360 * 5):
            truck.step(1 / 1360)
        assert truck.state.speed == 0.0 and truck.current == 0.0


# -- the world through the harness --------------------------------------------------------
def test_world_drives_past_markers_and_reports_ground_truth(drive_codec):
    world = WorldCore(layout('straight_track'), WorldParams(seed=5))
    drive = ScriptedDrive(duty=60)
    h = Harness(world, [drive], codec=drive_codec)
    h.run(30.0)
    passed = [e['marker'] for e in h.events if e['event'] == 'marker_passed']
    assert passed[:4] == ['L0', 'S0.1', 'L1', 'S1.1']
    assert all(abs(e['lateral']) < 5 for e in h.events)  # steering held, straight wire
    drive.duty = 0
    h.run(5.0)
    stops = [e for e in h.events if e['event'] == 'stopped']
    assert len(stops) == 1 and stops[0]['speed'] > 600


def test_a_slow_creep_after_a_rest_ends_in_a_rest_of_its_own():
    """The last creep of a controlled stop back onto the centre peaks under 10 mm/s.

    Its rest is the stop, not the rest before it.
    """
    world = WorldCore(layout('straight_track'), WorldParams(seed=5))
    for speed in (0.30, 0.10, 0.0, 0.0, 0.006, 0.003, 0.0, 0.0):
        world.vehicle.state.speed = speed
        world.truth.detect_stop()
    stops = [e for e in world.events if e['event'] == 'stopped']
    assert len(stops) == 2 and stops[0]['speed'] == 300 and stops[1]['speed'] == 6
    world.vehicle.state.speed = 0.0015  # drift below 2 mm/s is not moving
    world.truth.detect_stop()
    world.vehicle.state.speed = 0.0
    world.truth.detect_stop()
    assert len([e for e in world.events if e['event'] == 'stopped']) == 2


def test_watchdog_stall_opens_the_contactor(drive_codec):
    world = WorldCore(layout('straight_track'), WorldParams(seed=5))
    drive = ScriptedDrive(duty=60)
    h = Harness(world, [drive], codec=drive_codec)
    h.run(8.0)
    assert world.vehicle.contactor and world.vehicle.state.speed > 0.6
    drive.watchdog_running = False  # the traction loop has stalled; records keep coming
    h.run(0.25)
    assert world.vehicle.contactor  # traction still asks for it ...
    assert not world.vehicle.relay_closed  # ... but the trip relay released within 200 ms
    h.run(3.0)
    assert world.vehicle.state.speed == 0.0


def test_same_seed_same_samples_different_seed_differs(drive_codec):
    def samples(seed: int) -> list[bytes]:
        world = WorldCore(layout('straight_track'), WorldParams(seed=seed))
        h = Harness(world, [ScriptedDrive(duty=60)], codec=drive_codec)
        got: list[bytes] = []
        h.taps.append(lambda rec, raw, now: got.append(raw) if rec == 'adc_snapshot' else None)
        h.run(10.0)
        return got

    a, b, c = samples(11), samples(11), samples(12)
    assert a == b and len(a) == 3400
    assert a != c


def test_adc_snapshot_every_sample_at_340_hz(drive_codec):
    world = WorldCore(layout('straight_track'), WorldParams(seed=1))
    h = Harness(world, [ScriptedDrive(duty=0)], codec=drive_codec)
    counts: dict[str, int] = {}
    h.taps.append(lambda rec, raw, now: counts.__setitem__(rec, counts.get(rec, 0) + 1))
    h.run(2.0)
    assert counts['adc_snapshot'] == 680
    assert counts['guide_wire'] == pytest.approx(200, abs=2)
    assert counts['wheel_odometry'] == pytest.approx(200, abs=2)


def test_the_snapshot_record_is_its_fields_in_order():
    lit, dark = list(range(10, 18)), list(range(200, 208))
    record = snapshot_record(lit, dark)
    assert list(record.items()) == list(zip(SNAPSHOT_FIELDS, lit + dark, strict=True))


def test_guide_wire_coils_balance_over_the_wire_and_fade_away():
    world = WorldCore(layout('straight_track'), WorldParams(seed=2))
    pickup = world.pickup
    nominal = pickup.p.nominal
    left, right = pickup.coils(5.0, 0.0, 0.0)
    assert abs(left - right) < 0.02 * nominal and left == pytest.approx(nominal, rel=0.03)
    left, right = pickup.coils(5.0, 0.05, 0.0)  # sensor point 5 cm left of the wire
    assert right > left
    assert max(pickup.coils(5.0, 1.0, 0.0)) < 0.05 * nominal  # far from every wire


def test_guide_wire_coils_agree_with_the_vectorised_field():
    """`coils` (scalar, candidate list) reads what `field` (numpy, every segment) implies."""
    world = WorldCore(layout('demo_1983'), WorldParams(seed=2))
    pickup = world.pickup
    pickup.p = dataclasses.replace(pickup.p, noise=0.0)
    xs = [x for w in world.wires for x, _y in w.points]
    ys = [y for w in world.wires for _x, y in w.points]
    rng = random.Random(5)
    poses = [(rng.uniform(min(xs) - 2, max(xs) + 2), rng.uniform(min(ys) - 2, max(ys) + 2),
              rng.uniform(-math.pi, math.pi)) for _ in range(300)]
    wire = world.wires[0]
    for k in range(0, len(wire.points), 7):  # along a wire, in small steps: cached candidates
        (x, y), h = wire.points[k], wire.headings[k]
        poses.append((x + 0.03 * math.sin(h), y - 0.03 * math.cos(h), h))
    on_wire, paths = 0, set()
    for x, y, h in poses:
        half = pickup.p.coil_spacing / 2.0
        lx, ly = -math.sin(h), math.cos(h)
        field = pickup.field(np.array([[x + half * lx, y + half * ly],
                                       [x - half * lx, y - half * ly]]))
        expect = [min(max(round(pickup.p.gain * abs(bx * lx + by * ly) * 4 * math.pi), 0), 4095)
                  for bx, by, _bz in field]
        got = pickup.coils(x, y, h)
        assert all(abs(g - e) <= 1 for g, e in zip(got, expect, strict=True)), (x, y, h)
        on_wire += max(got) > 0.5 * pickup.p.nominal
        paths.add('numpy' if len(pickup._near) > SCALAR_SEGMENTS else 'scalar')
    assert on_wire >= 20  # the walk along the wire did read the wire
    assert paths == {'numpy', 'scalar'}  # straights and curves both summed


LOAD_FIRST = {'first': 'load', 'second': 'off', 'station_request': 1}


def _command_conveyors(world: WorldCore, seconds: float, every: int = 17) -> None:
    """Step `world`, sending LOAD_FIRST each `every` samples (load handling's 50 ms period)."""
    for k in range(round(340 * seconds)):
        if k % every == 0:
            world.on_record('conveyor_command', LOAD_FIRST, world.time)
        world.step()


def _at_stop_marker(lay, short: float) -> WorldCore:
    """Return a world with the truck at rest, its sensor `short` m before S0's stop marker."""
    world = WorldCore(lay, WorldParams(seed=3))
    card = next(m for m in lay.markers if m.station == 'S0')
    st = world.vehicle.state
    st.x = card.centre[0] - short - world.p.electruk.wheelbase
    st.y, st.heading = 0.0, 0.0
    return world


def test_conveyor_transfer_only_when_aligned_and_commanded(drive_codec):
    lay = layout('straight_track')
    world = _at_stop_marker(lay, 0.02)
    _command_conveyors(world, 5.0)
    assert world.conveyors.loads[0] and world.conveyors.station_loads['S0'] == 0
    # Not aligned: 0.3 m off, nothing moves.
    world2 = _at_stop_marker(lay, 0.3)
    _command_conveyors(world2, 5.0)
    assert not world2.conveyors.loads[0] and world2.conveyors.station_loads['S0'] == 1


def test_conveyors_stop_when_their_commands_stop(drive_codec):
    """A load-handling processor gone silent leaves no conveyor running (conveyor_timeout)."""
    world = _at_stop_marker(layout('straight_track'), 0.02)
    _command_conveyors(world, 1.0)  # a 3.2 s transfer, a third done
    world.on_record('conveyor_command', LOAD_FIRST, world.time)  # the last command
    started = world.conveyors.transfer
    assert 0.25 < started < 0.4
    for _ in range(round(340 * world.p.conveyor_timeout) + 1):
        world.step()  # within the timeout the last command still runs them
    held = world.conveyors.transfer
    assert held - started == pytest.approx(world.p.conveyor_timeout * world.p.conveyor_speed
                                           / world.p.transfer_length, abs=0.002)
    for _ in range(340 * 5):
        world.step()
    c = world.conveyors
    assert c.transfer == held and not c.loads[0] and c.station_loads['S0'] == 1
    _command_conveyors(world, 3.0)  # commands again: the transfer completes
    assert world.conveyors.loads[0]


# -- camera ----------------------------------------------------------------------------------
@pytest.mark.parametrize('offset, angle_deg', [(0.0, 0.0), (0.04, 0.0), (-0.07, 0.0),
                                               (0.02, 8.0), (-0.03, -12.0)])
def test_camera_truth_agrees_with_the_pose_to_one_pixel(offset, angle_deg):
    lay = layout('tape_1991')
    tape = lay.paths['circle']
    cam = BinaryCamera(CameraParams(specks=0), [tape], np.random.default_rng(0))
    x, y, h = tape.pose_at(2.0)
    # Window centre `offset` to the right of the tape, turned by angle_deg.
    cx, cy = x + math.sin(h) * offset, y - math.cos(h) * offset
    heading = h + math.radians(angle_deg)
    frame = cam.render(cx, cy, heading, noise=False)
    eps_d, eps_theta = cam.truth(cx, cy, heading)
    col_mm = CameraParams().width / 128 * 1000
    # Tape centre column in the middle row, measured from the image.
    row = frame[32]
    cols = np.flatnonzero(row)
    centre_col = (cols[0] + cols[-1] + 1) / 2
    measured_d = (64 - centre_col) * col_mm / 1000  # + = tape left of the window centre
    expected_d = eps_d / math.cos(eps_theta)  # the lateral line meets the tape there
    assert abs(measured_d - expected_d) <= col_mm / 1000
    assert eps_d == pytest.approx(offset, abs=0.003)
    assert math.degrees(eps_theta) == pytest.approx(-angle_deg, abs=1.0)


@pytest.mark.parametrize('name', ['tape_1991', 'signs_1991', 'junction_1991'])
def test_a_frame_from_the_segments_that_reach_the_window_is_the_whole_frame(name, monkeypatch):
    """The window's own segments give every pixel, at junctions and square ends too."""
    lay = layout(name)
    tapes = [p for p in lay.paths.values() if p.width > 0.0]
    cam = BinaryCamera(CameraParams(specks=0), tapes, np.random.default_rng(0))
    rng = np.random.default_rng(7)
    poses = []
    for tape in tapes:
        for k in range(0, len(tape.points) - 1, 13):
            (x, y), d = tape.points[k], tape.points[k + 1] - tape.points[k]
            poses.append((x + rng.normal(0, 0.08), y + rng.normal(0, 0.08),
                          math.atan2(d[1], d[0]) + rng.normal(0, 0.5)))
    fast = [cam.render(*pose, noise=False) for pose in poses]
    monkeypatch.setattr(BinaryCamera, '_crossing', lambda self, tape, idx, *_: idx)
    every = [cam.render(*pose, noise=False) for pose in poses]
    assert sum(int(f.sum()) for f in fast) > 0.02 * len(poses) * fast[0].size  # tape seen
    assert all(np.array_equal(a, b) for a, b in zip(fast, every, strict=True))


# -- layouts --------------------------------------------------------------------------------
def test_shipped_layouts_load():
    demo = layout('demo_1983')
    assert {m.name for m in demo.markers if m.kind == 'location'} == {'L0', 'L1', 'L2', 'L3'}
    assert len(demo.paths) == 2 and set(demo.stations) == {'W0', 'W1', 'W2', 'W3'}
    assert sum(1 for m in demo.markers if m.station == 'W2') == 2
    for loc in (m for m in demo.markers if m.kind == 'location' and m.path == 'A'):
        stops = [m for m in demo.markers if m.kind == 'stop' and m.path == loc.path
                 and 0 < m.at - loc.at < 3]
        assert all(m.at - loc.at >= 1.0 for m in stops)  # >= 1 m before its stop markers
    assert layout('sensor_rig').kind == 'rig'
    assert layout('tape_1991').vehicle == 'concic2'


@pytest.mark.parametrize('edit, key, value', [
    (('kind: wire', 'kind: maglev'), 'kind', "'maglev'"),
    (('straight: 60.0', 'straight: -4'), 'wires[0].segments[0].straight', '-4'),
    (('identity: 3, path: A', 'identity: 7, path: A'), 'markers[6].identity', '7'),
    (('station: S2, path: A', 'station: S9, path: A'), 'markers[5].station', "'S9'"),
    (('at: 44.0', 'at: 75.0'), 'markers[6].at', '75.0'),
    (('start: {path: A, at: 2.0}', 'start: {path: Q, at: 2.0}'), 'start.path', "'Q'"),
])
def test_bad_layout_names_file_key_value(tmp_path, edit, key, value):
    text = layout_path('straight_track').read_text().replace(*edit)
    bad = tmp_path / 'straight_track.yaml'
    bad.write_text(text)
    with pytest.raises(LayoutError) as info:
        load_layout(bad)
    msg = str(info.value)
    assert str(bad) in msg and key in msg and value in msg
