"""The world core: truck, floor, wires or tape, markers, conveyors and sensors, ROS-free.

Stepped once per marker-sensor sample (340 Hz by default, Baker 1983, 5.3.5.2). Inputs are the
hardware-side records (traction_drive, steering_command, conveyor_command) and the radio stop;
outputs are the hardware-side records due at this step, camera frames, the CONCIC-II's sonar
readings (agv_nodes/world/sonar.py) and ground-truth events.
The CONCIC-II's amplifiers are powered by its safety PAL (agv_nodes/world/safety_pal.py).
Everything is seeded: the same seed and inputs give the same samples.
"""

from __future__ import annotations

import math
import random
from typing import Any

import numpy as np

from agv_nodes.markers import snapshot_record
from agv_nodes.world import kernels
from agv_nodes.world.camera import BinaryCamera
from agv_nodes.world.concic2_dynamics import Concic2Dynamic
from agv_nodes.world.contact import footprint
from agv_nodes.world.conveyors import Conveyors
from agv_nodes.world.ground_truth import GroundTruth, nearest_path_offset
from agv_nodes.world.guide_wire import GuideWirePickup
from agv_nodes.world.layout import Layout
from agv_nodes.world.marker_sensor import MarkerSensorModel, lens_position
from agv_nodes.world.obstacles import Obstacles
from agv_nodes.world.safety_pal import SafetyPal, encoder_reading
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.sonar import Sonar
from agv_nodes.world.vehicles import Concic2, Electruk


def _mm_per_s(v: float) -> int:
    """Return a speed in m/s as the odometry record's signed 16-bit mm/s, clipped."""
    return int(min(max(round(v * 1000), -32768), 32767))


class _Every:
    """Fires `rate` times per simulated second on the sample clock (exact on average)."""

    def __init__(self, rate: float, sample_rate: float) -> None:
        self.ratio = rate / sample_rate
        # No sample before this one is due: the world tests it before calling due().
        self.next = 0

    def _fires(self, sample: int) -> bool:
        return math.floor(sample * self.ratio) > math.floor((sample - 1) * self.ratio)

    def due(self, sample: int) -> bool:
        """Return True when a record is due at `sample` (samples asked in increasing order)."""
        if sample < self.next:
            return False
        fires = self._fires(sample)
        # the next sample that fires: _fires(s) for s = sample + 1, ..., each floor worked out
        # once (floor(s * ratio) is the next test's floor((s - 1) * ratio))
        ratio, floor = self.ratio, math.floor
        following, level = sample + 1, floor(sample * ratio)
        while (reached := floor(following * ratio)) <= level:
            level = reached
            following += 1
        self.next = following
        return fires


class WorldCore:
    """The simulated hardware; see the module docstring (its events: its part `truth`)."""

    def __init__(self, layout: Layout, params: WorldParams | None = None, *,
                 start: tuple[str, float] | None = None,
                 station_loads: dict[str, int] | None = None) -> None:
        """Place the truck at the layout's start, or at `start` (path, at): a fleet's trucks.

        `station_loads` is the stations' loads, shared with the other trucks' worlds.
        """
        self.layout = layout
        self._start = start
        self.p = params or WorldParams()
        self.rng = random.Random(self.p.seed)
        self.np_rng = np.random.default_rng(self.p.seed)
        self.dt = 1.0 / self.p.sample_rate
        self.sample = 0
        self.wires = [w for w in layout.paths.values() if w.width == 0.0]
        self.tapes = [t for t in layout.paths.values() if t.width > 0.0]
        compiled = kernels.select(self.p.kernels)
        if layout.vehicle == 'electruk':
            self.vehicle: Electruk | Concic2 = Electruk(self.p.electruk, compiled)
        elif self.p.concic2.model == 'dynamic':
            self.vehicle = Concic2Dynamic(self.p.concic2)
        else:
            self.vehicle = Concic2(self.p.concic2)
        self._electruk = isinstance(self.vehicle, Electruk)
        self._place_vehicle()
        self.sensor = MarkerSensorModel(self.p.sensor, self.rng, compiled)
        # Only the Electruk carries Baker's marker sensor; the CONCIC-II reads its floor with
        # the cameras, so its world sends no ADC snapshots (340 a second nobody reads).
        self.marker_sensor = layout.vehicle == 'electruk'
        self.pickup = GuideWirePickup(self.p.pickup, self.wires, self.rng, compiled) \
            if self.wires else None
        self.camera = BinaryCamera(self.p.camera, self.tapes, self.np_rng) if self.tapes else None
        self._wire_every = _Every(self.p.guide_wire_rate, self.p.sample_rate)
        self._odo_every = _Every(self.p.odometry_rate, self.p.sample_rate)
        self._conv_every = _Every(self.p.conveyor_rate, self.p.sample_rate)
        self._cam_every = _Every(self.p.camera_rate, self.p.sample_rate)
        self._drive_every = _Every(self.p.drive_status_rate, self.p.sample_rate)
        self.pal = SafetyPal(self.p.concic2) if isinstance(self.vehicle, Concic2) else None
        # The floor's obstacles (either truck's); the CONCIC-II's front sonar sees them.
        self.obstacles = Obstacles(list(layout.obstacles))
        self.sonar = Sonar(self.p.sonar, self.p.seed) if isinstance(self.vehicle, Concic2) \
            else None
        self._sonar_every = _Every(self.p.sonar.rate, self.p.sample_rate)
        self.radio_stop = False
        self.wire_powered = True  # the guide-wire generator (a fault test switches it off)
        self._last_watchdog: int | None = None
        self._watchdog_time = -1e9
        self._steer_time = -1e9
        self.conveyors = Conveyors(layout, self.p)
        if station_loads is not None:  # one floor: a load taken by one truck is gone for all
            self.conveyors.station_loads = station_loads
        self.bumper = False  # pressed by another truck: the drive is cut until a reset
        # records published, whole counts (the records carry the low byte)
        self.counters = {'guide_wire': 0, 'wheel_odometry': 0}
        self._odo_dist = [0.0, 0.0]  # m per driven wheel
        self._odo_time = 0.0
        self.events: list[dict[str, Any]] = []
        self.truth = GroundTruth(self)
        self._on_wire = True
        self._rig_s = layout.start_at

    # -- set-up ---------------------------------------------------------------------------
    def _place_vehicle(self) -> None:
        lay = self.layout
        pid, at = self._start or (lay.start_path, lay.start_at)
        lateral, heading = (0.0, 0.0) if self._start else (lay.start_lateral, lay.start_heading)
        x, y, h = lay.paths[pid].pose_at(at)
        h += heading
        x += -math.sin(h) * lateral
        y += math.cos(h) * lateral
        # The layout gives the sensor point (front axle / camera); place the reference point.
        ahead = (self.p.electruk.wheelbase if isinstance(self.vehicle, Electruk)
                 else self.p.concic2.camera_distance)
        st = self.vehicle.state
        st.x, st.y, st.heading = x - ahead * math.cos(h), y - ahead * math.sin(h), h
        if isinstance(self.vehicle, Electruk):
            self.vehicle.flux = 0.0

    @property
    def time(self) -> float:
        """Simulated seconds since start."""
        return self.sample * self.dt

    # -- inputs ---------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> None:
        """Apply a hardware-side input record that arrived at sim time `now`."""
        if record == 'traction_drive' and isinstance(self.vehicle, Electruk):
            if fields['watchdog'] != self._last_watchdog:
                self._last_watchdog = fields['watchdog']
                self._watchdog_time = now
            self.vehicle.set_drive(fields['armature_duty'] / 100.0, fields['field_duty'] / 100.0,
                                   bool(fields['field_forward']), bool(fields['armature_enable']),
                                   bool(fields['field_enable']), bool(fields['contactor']))
        elif record == 'steering_command':
            self._steer_time = now
            if self.pal is not None:
                self.pal.command(fields, now)
            if isinstance(self.vehicle, Electruk):
                self.vehicle.steer_demand = fields['angle'] / 1000.0
                self.vehicle.steer_enable = bool(fields['enable'])
            elif fields['mode'] == 'wheel_speeds':
                self.vehicle.set_wheels(fields['left_speed'] / 1000.0,
                                        fields['right_speed'] / 1000.0, bool(fields['enable']))
            else:
                self.vehicle.set_wheels(0.0, 0.0, False)
        elif record == 'conveyor_command':
            self.conveyors.on_command(fields, now)

    def hardware_reset(self) -> None:
        """Press the reset: the CONCIC-II's safety PAL latches clear; a pressed bumper frees."""
        self.bumper = False
        if self.pal is not None:
            self.pal.hardware_reset(self.time)

    def bump(self) -> None:
        """Another truck (or an obstacle) touched this one: a collision event, the drive cut.

        Modern (neither thesis has two trucks meet): the bumper switch is in the drive's safety
        circuit, as the radio stop is, and stays pressed until a reset.
        """
        if not self.bumper:
            self.bumper = True
            self.truth.event('collision')

    def set_radio_stop(self, on: bool) -> None:
        """Set the radio-control stop input (hw/radio_stop): no drive torque while set."""
        self.radio_stop = bool(on)

    # -- stepping -------------------------------------------------------------------------
    def step(self) -> dict[str, Any]:
        """Advance one sample; return {'records': {...}, 'frames': {...}, 'events': [...]}."""
        self.sample += 1
        sample = self.sample
        self.events = []
        if self.layout.kind == 'rig':
            return self._step_rig()
        dt, p, vehicle = self.dt, self.p, self.vehicle
        now = sample * dt  # self.time
        self._apply_safety(now)
        sub = dt / p.substeps
        if isinstance(vehicle, Electruk):  # a sample's substeps in one call
            vehicle.step(sub, p.substeps)
        else:
            for _ in range(p.substeps):
                vehicle.step(sub)
        records: dict[str, dict[str, Any]] = {}
        if self.marker_sensor:
            records['adc_snapshot'] = self._adc()
        # Each record's clock is tested here before its due() is called: most samples send none.
        if self.pickup is not None and sample >= (every := self._wire_every).next \
                and every.due(sample):
            records['guide_wire'] = self._guide_wire(self.pickup)
        if sample >= (every := self._odo_every).next and every.due(sample):
            records['wheel_odometry'] = self._odometry()
        if self.pal is not None and sample >= (every := self._drive_every).next \
                and every.due(sample):
            records['drive_status'] = self.pal.record(self.radio_stop)
        at_rest = abs(vehicle.state.speed) <= 0.01
        if (moved := self.conveyors.step(now, dt, at_rest, self.lens_pose)) is not None:
            self.truth.event('load_moved', marker=moved)
        if sample >= (every := self._conv_every).next and every.due(sample):
            records['conveyor_status'] = self.conveyors.status(at_rest, self.lens_pose)
        frames = {}
        if self.camera is not None and sample >= (every := self._cam_every).next \
                and every.due(sample):
            frames = self._frames(self.camera)
        if self._electruk and self.obstacles.by_name and not self.bumper:
            # The tug has no sonar: its bumper finds an obstacle, as it finds another truck.
            s = vehicle.state
            if self.obstacles.touching(footprint(s.x, s.y, s.heading, p.electruk)):
                self.bump()
        sonar = None  # hw/sonar: a reading (m) when a ping is due
        if self.sonar is not None and sample >= (every := self._sonar_every).next \
                and every.due(sample) and self.p.sonar.enabled:
            s = vehicle.state
            sonar = self.sonar.ping(s.x, s.y, s.heading, self.obstacles)
        self.truth.detect_stop()
        self.truth.detect_drive_off()
        return {'records': records, 'frames': frames, 'events': self.events, 'sonar': sonar}

    def _apply_safety(self, now: float) -> None:
        v = self.vehicle
        v.radio_stop = self.radio_stop or self.bumper
        if isinstance(v, Electruk):
            # The trip relay's monostable: no watchdog change for 200 ms releases the relay and
            # with it the main contactor; retriggering closes it again (Baker 1983, B.2.1).
            v.relay_closed = now - self._watchdog_time <= self.p.drive_watchdog
            if now - self._steer_time > self.p.steering_timeout:
                v.steer_enable = False
        elif self.pal is not None:
            # The safety PAL powers the amplifiers only in its ready state: a fault (its
            # watchdog among them) cuts them and the wheels coast down together, as after a
            # motor-off command (Rajagopalan 1991, 6.3.11).
            self.pal.step(now)
            if not self.pal.powered:
                v.enable = False

    # -- sensors --------------------------------------------------------------------------
    def lens_pose(self) -> tuple[tuple[float, float], float]:
        """Marker-sensor lens position and truck heading (on the rig: the belt position)."""
        if self.layout.kind == 'rig':
            s = self.vehicle.state
            return (s.x, s.y), s.heading
        h = self.vehicle.state.heading
        return lens_position(self.vehicle.sensor_point, h, self.layout.sensor_lateral), h

    def _adc(self) -> dict[str, int]:
        # lens_pose() of the Electruk, the one truck with a marker sensor, inline (the same
        # arithmetic, 340 times a simulated second), and its ride height under the payload
        s, p = self.vehicle.state, self.p
        h = s.heading
        cos_h, sin_h, lateral = math.cos(h), math.sin(h), self.layout.sensor_lateral
        sx, sy = s.x + p.electruk.wheelbase * cos_h, s.y + p.electruk.wheelbase * sin_h
        lens = (sx + sin_h * lateral, sy - cos_h * lateral)
        truth = self.truth
        truth.cards_near(lens)
        lit, dark = self.sensor.snapshot(lens, h, truth.near_cards,
                                         p.electruk.payload / 1000.0 * p.ride_height_per_tonne)
        if truth.near:
            truth.marker_passages(lens, h)
        return snapshot_record(lit, dark)

    def _guide_wire(self, pickup: GuideWirePickup) -> dict[str, int]:
        sx, sy = self.vehicle.sensor_point
        left, right = pickup.coils(sx, sy, self.vehicle.state.heading)
        if not self.wire_powered:  # generator off: the coils pick up nothing
            left = right = 0
        self.counters['guide_wire'] += 1
        on_wire = max(left, right) > 0.25 * self.p.pickup.nominal
        if on_wire != self._on_wire:
            self._on_wire = on_wire
            self.truth.event('wire_found' if on_wire else 'wire_lost')
        return {'left_coil': left, 'right_coil': right,
                'sample': self.counters['guide_wire'] & 0xFF}

    def _odometry(self) -> dict[str, int]:
        left, right = self.vehicle.wheel_speeds()
        if self.pal is not None:  # an injected encoder fault: that wheel's count stands still
            left, right = encoder_reading(self.p.concic2.encoder_fault, left, right)
        self.counters['wheel_odometry'] += 1
        period = self.time - self._odo_time
        self._odo_time = self.time
        self._odo_dist[0] += left * period
        self._odo_dist[1] += right * period
        return {'left_speed': _mm_per_s(left), 'right_speed': _mm_per_s(right),
                'left_distance': int(round(self._odo_dist[0] * 1000)) & 0xFFFF,
                'right_distance': int(round(self._odo_dist[1] * 1000)) & 0xFFFF,
                'sample': self.counters['wheel_odometry'] & 0xFF}

    def _frames(self, camera: BinaryCamera) -> dict[str, np.ndarray]:
        s = self.vehicle.state
        lc = self.p.concic2.camera_distance
        frames = {}
        for name, sign in (('front', 1.0), ('rear', -1.0)):
            if name == 'rear' and not self.p.rear_camera:
                continue
            cx = s.x + sign * lc * math.cos(s.heading)
            cy = s.y + sign * lc * math.sin(s.heading)
            heading = s.heading if sign > 0 else s.heading + math.pi
            frames[name] = camera.render(cx, cy, heading)
        return frames

    # -- the belt rig (Baker 1983, 7.1.1) ---------------------------------------------------
    def _step_rig(self) -> dict[str, Any]:
        rig = self.layout.rig
        path = self.layout.paths[self.layout.start_path]
        self._rig_s += float(rig.get('speed', 1.0)) * self.dt
        x, y, h = path.pose_at(self._rig_s)
        # The lens runs along the belt line; cards sit at their own standoff beside it.
        lens = (x, y)
        st = self.vehicle.state
        st.x, st.y, st.heading, st.speed = x, y, h, float(rig.get('speed', 1.0))
        lit, dark = self.sensor.snapshot(lens, h, self.layout.markers,
                                         float(rig.get('height', 0.0)))
        self.truth.marker_passages(lens, h)
        return {'records': {'adc_snapshot': snapshot_record(lit, dark)}, 'frames': {},
                'events': self.events}

    # -- ground-truth views for the node ----------------------------------------------------
    def nearest_path_offset(self, x: float, y: float) -> float:
        """Signed lateral offset (m, + = left) of (x, y) from the nearest wire or tape."""
        return nearest_path_offset(self.layout, x, y)

    def pose(self) -> tuple[float, float, float, float]:
        """(x, y, heading, speed) of the vehicle reference point."""
        s = self.vehicle.state
        return s.x, s.y, s.heading, s.speed

    def done_rig(self) -> bool:
        """Return True when the rig's belt has run out."""
        path = self.layout.paths[self.layout.start_path]
        return self.layout.kind == 'rig' and self._rig_s >= path.length
