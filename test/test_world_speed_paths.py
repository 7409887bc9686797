"""The world's fast paths give the same numbers, to the last bit, as the plain ones they replace.

The marker sensor's snapshot (card bounding test, inline detector model, conversions worked out a
noise block at a time) against adc(signals(optics())) and the per-snapshot conversion as first
written; the guide-wire pickup's numpy sum against `field`; the Electruk's substeps in one call
against one call a substep.
"""

from __future__ import annotations

import dataclasses
import math
import random

import numpy as np
import pytest

from agv_nodes.markers import ELEMENT_HEIGHT, ELEMENT_WIDTH
from agv_nodes.world.core import WorldCore
from agv_nodes.world.guide_wire import SCALAR_SEGMENTS
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.marker_optics import EDGE_ON, box_blur_cover, cdf, white_runs
from agv_nodes.world.marker_sensor import NOISE_PER_SNAPSHOT, MarkerSensorModel
from agv_nodes.world.settings import ElectrukParams, SensorParams, WorldParams
from agv_nodes.world.vehicles import Electruk


def layout(name: str):
    return load_layout(layout_path(name))


def plain_optics(p: SensorParams, lens, heading: float, cards, height: float = 0.0):
    """Return the optics as first written: every card in 0.6 m, every detector, no shortcut."""
    fx, fy = math.cos(heading), math.sin(heading)
    ax, ay = fy, -fx
    out = [(1.0, 0.0)] * 8
    for card in cards:
        cx, cy = card.centre
        nx, ny = card.normal
        ex, ey = card.along
        dx, dy = cx - lens[0], cy - lens[1]
        if dx * dx + dy * dy > 0.36:
            continue
        for d in range(8):
            x_off = (1.5 - d % 4) * p.column_pitch + p.skew[d]
            rx, ry = ax * p.focus + fx * x_off, ay * p.focus + fy * x_off
            norm = math.hypot(rx, ry)
            rx, ry = rx / norm, ry / norm
            denom = rx * nx + ry * ny
            if denom > EDGE_ON:
                continue
            t = (dx * nx + dy * ny) / denom
            if not 0.05 < t < 0.8:
                continue
            hx, hy = lens[0] + t * rx - cx, lens[1] + t * ry - cy
            value = _plain_detector(p, card, d, hx * ex + hy * ey, t, -denom, height)
            if value is not None:
                out[d] = value
    return out


def _plain_detector(p: SensorParams, card, d: int, u: float, rng_: float, cos_inc: float,
                    height: float):
    half_card = len(card.rows[0]) * ELEMENT_WIDTH / 2.0
    scale = rng_ / p.focus
    w = p.aperture_width * scale / max(cos_inc, 0.3)
    if abs(u) > half_card + w + 0.02:
        return None
    sigma = math.hypot(p.base_blur, p.defocus_blur * (rng_ - p.focus))
    lo, hi = u - w / 2.0, u + w / 2.0
    v = (p.row_pitch / 2.0 if d < 4 else -p.row_pitch / 2.0) * scale - (card.height + height)
    big = p.aperture_height * scale
    weights = (_trapezoid_mass(0.0 - v, ELEMENT_HEIGHT - v, big, p.flat_height),
               _trapezoid_mass(-ELEMENT_HEIGHT - v, 0.0 - v, big, p.flat_height))
    white_cover = 0.0
    for row, weight in zip(card.rows, weights, strict=True):
        if weight <= 1e-6:
            continue
        cover = 0.0
        for a, b in white_runs(row):
            cover += box_blur_cover(a - half_card, b - half_card, lo, hi, sigma)
        white_cover += weight * cover / w
    return (p.focus / rng_) ** 2 * cos_inc, white_cover


def _trapezoid_mass(z0: float, z1: float, height: float, flat: float) -> float:
    b = height / 2.0
    a = flat * b
    return (cdf(z1, a, b) - cdf(z0, a, b)) / (a + b)


def _adc8(value: float) -> int:
    return 0 if value <= 0 else 255 if value >= 255 else int(value + 0.5)


class PlainConversion:
    """The per-snapshot conversion as first written: 17 normals a snapshot, in order."""

    def __init__(self, model: MarkerSensorModel, seed_rng: random.Random) -> None:
        self.p = model.p
        self.normals = np.random.default_rng(seed_rng.getrandbits(64))
        self.noise: list[float] = []
        self.at = 0

    def adc(self, signals: list[float]) -> tuple[list[int], list[int]]:
        p = self.p
        at = self.at
        if at + NOISE_PER_SNAPSHOT > len(self.noise):
            self.noise = self.normals.standard_normal(NOISE_PER_SNAPSHOT * 256).tolist()
            at = 0
        self.at = at + NOISE_PER_SNAPSHOT
        z = self.noise[at:at + NOISE_PER_SNAPSHOT]
        base = p.dark_level + p.ambient + z[16] * p.ambient_noise
        return ([_adc8(base + signals[d] + z[d] * p.noise) for d in range(8)],
                [_adc8(base + z[8 + d] * p.noise) for d in range(8)])


def _lens_poses(lay, count: int, seed: int) -> list[tuple[tuple[float, float], float]]:
    """Lens poses over and around the layout's cards: in view, at the edge, out of view."""
    rng = random.Random(seed)
    poses = []
    for _ in range(count):
        card = rng.choice(lay.markers)
        nx, ny = card.normal
        ex, ey = card.along
        standoff = card.standoff + rng.uniform(-0.03, 0.03)
        along = rng.uniform(-0.4, 0.4) if rng.random() < 0.7 else rng.uniform(-0.03, 0.03)
        lens = (card.centre[0] + standoff * nx + along * ex,
                card.centre[1] + standoff * ny + along * ey)
        heading = math.atan2(ey, ex) + rng.uniform(-0.3, 0.3)
        poses.append((lens, heading))
    return poses


@pytest.mark.parametrize('name', ['demo_1983', 'straight_track'])
def test_snapshot_equals_adc_of_signals_of_optics_bit_for_bit(name):
    lay = layout(name)
    params = SensorParams(ambient=3.0)
    fast = MarkerSensorModel(params, random.Random(7))
    plain = MarkerSensorModel(params, random.Random(7))
    conversion = PlainConversion(plain, random.Random(7))
    poses = _lens_poses(lay, 2000, seed=3)
    quiet = 0
    for k, (lens, heading) in enumerate(poses):
        if k == 900:  # the node changes the ambient light mid-block
            fast.p.ambient = plain.p.ambient = 40.0
        height = 0.01 if k % 3 == 0 else 0.0
        optics = plain_optics(plain.p, lens, heading, lay.markers, height)
        quiet += optics == [(1.0, 0.0)] * 8
        want = conversion.adc(plain.signals(optics))
        assert fast.snapshot(lens, heading, lay.markers, height) == want, (k, lens, heading)
    assert 100 < quiet < 1900  # both paths taken: cards in view and none


def test_adc_equals_the_plain_conversion_bit_for_bit():
    params = SensorParams(noise=2.0, ambient=250.0, ambient_noise=3.0)  # saturating too
    fast = MarkerSensorModel(params, random.Random(11))
    conversion = PlainConversion(fast, random.Random(11))
    rng = random.Random(2)
    for _ in range(700):  # across blocks
        signals = [rng.uniform(-20.0, 40.0) for _ in range(8)]
        assert fast.adc(signals) == conversion.adc(signals)


@pytest.mark.parametrize('name', ['demo_1983', 'straight_track'])
@pytest.mark.parametrize('skew', [0.0, 0.004])
def test_optics_equals_the_plain_optics_bit_for_bit(name, skew):
    """Cards passed over by the bounding test are those no detector sees."""
    lay = layout(name)
    params = SensorParams(skew=tuple(skew * (d % 3 - 1) for d in range(8)))
    model = MarkerSensorModel(params, random.Random(0))
    seen = 0
    for lens, heading in _lens_poses(lay, 3000, seed=9):
        for card in lay.markers:
            want = plain_optics(params, lens, heading, [card], 0.02)
            assert model.optics(lens, heading, [card], 0.02) == want, (lens, heading, card)
            seen += want != [(1.0, 0.0)] * 8
    assert seen > 300


def test_coils_numpy_sum_equals_field_bit_for_bit():
    world = WorldCore(layout('demo_1983'), WorldParams(seed=2))
    pickup = world.pickup
    pickup.p = dataclasses.replace(pickup.p, noise=0.0)
    wire = world.wires[0]
    half = pickup.p.coil_spacing / 2.0
    checked = 0
    for k in range(0, len(wire.points), 3):
        (x, y), h = wire.points[k], wire.headings[k]
        for off in (-0.2, -0.03, 0.0, 0.05, 0.3):
            px, py = x + off * math.sin(h), y - off * math.cos(h)
            pickup.coils(px, py, h)  # the candidate list, as coils keeps it
            if len(pickup._near) <= SCALAR_SEGMENTS:
                continue
            lx, ly = -math.sin(h), math.cos(h)
            points = ((px + half * lx, py + half * ly), (px - half * lx, py - half * ly))
            keep = np.hypot(pickup._near_mid[:, 0] - px, pickup._near_mid[:, 1] - py) \
                - 0.5 * pickup._near_length < pickup.p.reach
            field = pickup.field(np.array(points), segments=pickup._near_idx[keep])
            want = [bx * lx + by * ly for bx, by, _bz in field.tolist()]
            assert pickup._lateral_numpy(points, px, py, lx, ly) == want
            checked += 1
    assert checked > 50


def test_electruk_substeps_in_one_call_equal_one_call_each():
    one, each = Electruk(ElectrukParams()), Electruk(ElectrukParams())
    rng = random.Random(4)
    dt = 1 / 1360
    for k in range(3000):
        if k % 150 == 0:  # new drive and steering inputs, forward, plug braking, coasting
            drive = (rng.uniform(0, 0.8), rng.uniform(0.2, 1.0), rng.random() < 0.7,
                     rng.random() < 0.8, True, rng.random() < 0.9)
            demand, enable = rng.uniform(-0.8, 0.8), rng.random() < 0.8
            for truck in (one, each):
                truck.set_drive(*drive)
                truck.steer_demand, truck.steer_enable = demand, enable
        one.step(dt, 4)
        for _ in range(4):
            each.step(dt)
        assert vars(one.state) == vars(each.state)
        assert (one.flux, one.current, one.steer) == (each.flux, each.current, each.steer)
