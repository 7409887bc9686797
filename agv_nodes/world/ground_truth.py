"""The world's ground truth: marker passages, stops and the drive going off (ROS-free).

A mixin of WorldCore (agv_nodes/world/core.py), which calls it every sample. Each event goes
into `events` as the world_event record's fields (docs/records.md), stamped with the sim time:
what the fault and stop tests and agv-report judge the truck by, never seen by the truck's own
nodes. WorldCore provides `layout`, `vehicle`, `p`, `time`, `events`, `lens_pose` and the
bookkeeping attributes it initialises (`_near`, `_near_at`, `_card_side`, `_moving`,
`_peak_speed`, `_pushing`, `_event_count`).
"""

from __future__ import annotations

import math

from agv_nodes.world.layout import Marker
from agv_nodes.world.marker_sensor import axis_on_card

NEAR_MOVE = 0.3  # m the lens moves before the list of cards near it is redone
NEAR_MOVE_SQUARED = NEAR_MOVE ** 2


class GroundTruth:
    """What happened, as the world sees it (see the module docstring)."""

    def _cards_near(self, lens: tuple[float, float]) -> None:
        """Return the markers the lens may see (or pass) until it has moved NEAR_MOVE from here.

        The optics and the passage truth look no further than 0.6 m; a list of the cards within
        0.6 m + NEAR_MOVE, refreshed when the lens has moved NEAR_MOVE, holds every one of them
        and spares a pass over every marker of the floor at 340 Hz.
        """
        at = self._near_at
        if at is not None and (dx := lens[0] - at[0]) * dx + (dy := lens[1] - at[1]) * dy \
                < NEAR_MOVE_SQUARED:
            return
        self._near_at = lens
        reach = (0.6 + NEAR_MOVE) ** 2
        self._near = [(i, m) for i, m in enumerate(self.layout.markers)
                      if (m.centre[0] - lens[0]) ** 2 + (m.centre[1] - lens[1]) ** 2 < reach]
        self._near_cards = [m for _i, m in self._near]
        kept = {i for i, _m in self._near}
        for i in [i for i in self._card_side if i not in kept]:
            del self._card_side[i]  # out of sight: its side is news again when it comes back

    def _marker_passages(self, lens: tuple[float, float], heading: float) -> None:
        for i, m in self._near:
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            if dx * dx + dy * dy > 0.36:
                self._card_side.pop(i, None)
                continue
            on_card = axis_on_card(lens, heading, m)
            if on_card is None:
                continue
            t, u, _cos = on_card
            before = self._card_side.get(i)
            self._card_side[i] = u
            if before is not None and (before < 0.0) != (u < 0.0):
                self._event('marker_passed', marker=m, error=(t - self.p.sensor.focus) * 1000)

    def _detect_stop(self) -> None:
        v = abs(self.vehicle.state.speed)
        if v > self._peak_speed:
            self._peak_speed = v
        # Moving from 2 mm/s: a controlled stop's last creep back onto the centre peaks under
        # 10 mm/s, and a 10 mm/s threshold would leave its final rest unreported (the rest
        # before it, 3-4 mm short, would count as the stop).
        if v > 0.002:
            self._moving = True
        elif self._moving and v < 1e-4:
            self._moving = False
            nearest, err = self._nearest_stop_marker()
            self._event('stopped', marker=nearest, error=err * 1000 if nearest else 0.0,
                        speed=self._peak_speed)
            self._peak_speed = 0.0

    def _detect_drive_off(self) -> None:
        """Ground truth for the fault tests: the moment a moving Electruk stops being driven."""
        pushing = getattr(self.vehicle, 'pushing', None)
        if pushing is None:
            return
        if self._pushing and not pushing and abs(self.vehicle.state.speed) > 0.01:
            self._event('drive_off')
        self._pushing = pushing

    def _nearest_stop_marker(self) -> tuple[Marker | None, float]:
        lens, heading = self.lens_pose()
        fx, fy = math.cos(heading), math.sin(heading)
        best, best_err = None, 0.0
        for m in self.layout.markers:
            if m.kind != 'stop':
                continue
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            along = dx * fx + dy * fy  # + = the lens is past the card centre
            if abs(along) < 0.5 and (best is None or abs(along) < abs(best_err)):
                best, best_err = m, along
        return best, best_err

    def _event(self, kind: str, marker: Marker | None = None, error: float = 0.0,
               speed: float | None = None) -> None:
        self._event_count = (self._event_count + 1) & 0xFF
        sx, sy = self.vehicle.sensor_point
        lateral = self.nearest_path_offset(sx, sy)
        stations = list(self.layout.stations)
        self.events.append({
            'event': kind,
            'marker_kind': marker.kind if marker else 'none',
            'identity': (marker.identity + (1 if marker.kind == 'stop' else 0)) if marker
            else 0xFF,
            'error': int(max(-32768, min(32767, round(error)))),
            'speed': int(round(1000 * (abs(self.vehicle.state.speed) if speed is None
                                       else speed))),
            'lateral': int(max(-32768, min(32767, round(lateral * 1000)))),
            'count': self._event_count,
            'station': stations.index(marker.station) if marker and marker.station else 0xFF,
            'time': self.time,
            'marker': marker.name if marker else '',
        })

    def nearest_path_offset(self, x: float, y: float) -> float:
        """Signed lateral offset (m, + = left) of (x, y) from the nearest wire or tape."""
        best = None
        for path in self.layout.paths.values():
            _s, lateral, _h = path.project(x, y)
            if best is None or abs(lateral) < abs(best):
                best = lateral
        return 0.0 if best is None else best
