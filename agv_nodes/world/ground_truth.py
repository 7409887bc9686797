"""The world's ground truth: marker passages, stops and the drive going off (ROS-free).

A part of WorldCore (agv_nodes/world/core.py), which calls it every sample. Each event goes
into the world's `events` as the world_event record's fields (docs/records.md), stamped with the
sim time: what the fault and stop tests and agv-report judge the truck by, never seen by the
truck's own nodes. What it reads of the world is written out as `TruthWorld`; its bookkeeping
(the cards near the lens, the side of each card the lens is on, whether the truck moves) is its
own.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from agv_nodes.world.layout import Layout, Marker
from agv_nodes.world.marker_sensor import axis_on_card
from agv_nodes.world.settings import WorldParams

NEAR_MOVE = 0.3  # m the lens moves before the list of cards near it is redone
NEAR_MOVE_SQUARED = NEAR_MOVE ** 2


class TruthWorld(Protocol):
    """What the ground truth reads of the world (WorldCore)."""

    layout: Layout  # replaced whole when a marker is covered (agv-fleet-sim's blockedMarker)
    vehicle: Any  # Electruk or Concic2: state, sensor_point, and the Electruk's `pushing`
    p: WorldParams
    events: list[dict[str, Any]]  # this sample's events, renewed by the world each step

    @property
    def time(self) -> float:
        """Simulated seconds since start."""
        ...

    def lens_pose(self) -> tuple[tuple[float, float], float]:
        """Return the marker-sensor lens position and the truck's heading."""
        ...


def nearest_path_offset(layout: Layout, x: float, y: float) -> float:
    """Return the signed lateral offset (m, + = left) of (x, y) from the nearest wire or tape."""
    best = None
    for path in layout.paths.values():
        _s, lateral, _h = path.project(x, y)
        if best is None or abs(lateral) < abs(best):
            best = lateral
    return 0.0 if best is None else best


class GroundTruth:
    """What happened, as the world sees it (see the module docstring)."""

    def __init__(self, world: TruthWorld) -> None:
        self.world = world
        self.event_count = 0
        self.pushing = False
        self.card_side: dict[int, float] = {}
        self.near_at: tuple[float, float] | None = None  # lens position of the last `near`
        self.near: list[tuple[int, Marker]] = []  # (index, marker) the lens may reach
        self.near_cards: list[Marker] = []
        self.moving = False
        self.peak_speed = 0.0

    def forget_cards(self) -> None:
        """Drop what is known of the cards near the lens (the layout's markers changed)."""
        self.near_at, self.card_side = None, {}

    def cards_near(self, lens: tuple[float, float]) -> None:
        """Return the markers the lens may see (or pass) until it has moved NEAR_MOVE from here.

        The optics and the passage truth look no further than 0.6 m; a list of the cards within
        0.6 m + NEAR_MOVE, refreshed when the lens has moved NEAR_MOVE, holds every one of them
        and spares a pass over every marker of the floor at 340 Hz.
        """
        at = self.near_at
        if at is not None and (dx := lens[0] - at[0]) * dx + (dy := lens[1] - at[1]) * dy \
                < NEAR_MOVE_SQUARED:
            return
        self.near_at = lens
        reach = (0.6 + NEAR_MOVE) ** 2
        self.near = [(i, m) for i, m in enumerate(self.world.layout.markers)
                     if (m.centre[0] - lens[0]) ** 2 + (m.centre[1] - lens[1]) ** 2 < reach]
        self.near_cards = [m for _i, m in self.near]
        kept = {i for i, _m in self.near}
        for i in [i for i in self.card_side if i not in kept]:
            del self.card_side[i]  # out of sight: its side is news again when it comes back

    def marker_passages(self, lens: tuple[float, float], heading: float) -> None:
        """Note a marker_passed event for each card near the lens whose centre it crossed."""
        side = self.card_side
        for i, m in self.near:
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            if dx * dx + dy * dy > 0.36:
                side.pop(i, None)
                continue
            on_card = axis_on_card(lens, heading, m)
            if on_card is None:
                continue
            t, u, _cos = on_card
            before = side.get(i)
            side[i] = u
            if before is not None and (before < 0.0) != (u < 0.0):
                self.event('marker_passed', marker=m,
                           error=(t - self.world.p.sensor.focus) * 1000)

    def detect_stop(self) -> None:
        """Note a `stopped` event when the truck comes to rest (with the nearest stop card)."""
        v = abs(self.world.vehicle.state.speed)
        if v > self.peak_speed:
            self.peak_speed = v
        # Moving from 2 mm/s: a controlled stop's last creep back onto the centre peaks under
        # 10 mm/s, and a 10 mm/s threshold would leave its final rest unreported (the rest
        # before it, 3-4 mm short, would count as the stop).
        if v > 0.002:
            self.moving = True
        elif self.moving and v < 1e-4:
            self.moving = False
            nearest, err = self.nearest_stop_marker()
            self.event('stopped', marker=nearest, error=err * 1000 if nearest else 0.0,
                       speed=self.peak_speed)
            self.peak_speed = 0.0

    def detect_drive_off(self) -> None:
        """Ground truth for the fault tests: the moment a moving Electruk stops being driven."""
        vehicle = self.world.vehicle
        pushing = getattr(vehicle, 'pushing', None)
        if pushing is None:
            return
        if self.pushing and not pushing and abs(vehicle.state.speed) > 0.01:
            self.event('drive_off')
        self.pushing = pushing

    def nearest_stop_marker(self) -> tuple[Marker | None, float]:
        """Return the stop card nearest the lens within 0.5 m and the lens's distance past it."""
        lens, heading = self.world.lens_pose()
        fx, fy = math.cos(heading), math.sin(heading)
        best, best_err = None, 0.0
        for m in self.world.layout.markers:
            if m.kind != 'stop':
                continue
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            along = dx * fx + dy * fy  # + = the lens is past the card centre
            if abs(along) < 0.5 and (best is None or abs(along) < abs(best_err)):
                best, best_err = m, along
        return best, best_err

    def event(self, kind: str, marker: Marker | None = None, error: float = 0.0,
              speed: float | None = None) -> None:
        """Append one event (the world_event record's fields) to the world's events."""
        world = self.world
        vehicle = world.vehicle
        self.event_count = (self.event_count + 1) & 0xFF
        sx, sy = vehicle.sensor_point
        lateral = nearest_path_offset(world.layout, sx, sy)
        stations = list(world.layout.stations)
        world.events.append({
            'event': kind,
            'marker_kind': marker.kind if marker else 'none',
            'identity': (marker.identity + (1 if marker.kind == 'stop' else 0)) if marker
            else 0xFF,
            'error': int(max(-32768, min(32767, round(error)))),
            'speed': int(round(1000 * (abs(vehicle.state.speed) if speed is None
                                       else speed))),
            'lateral': int(max(-32768, min(32767, round(lateral * 1000)))),
            'count': self.event_count,
            'station': stations.index(marker.station) if marker and marker.station else 0xFF,
            'time': world.time,
            'marker': marker.name if marker else '',
        })
