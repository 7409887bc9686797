"""The truck's two conveyors and the workstations' loads (Baker 1983, 6.3.2), ROS-free.

A load moves between a truck conveyor and a workstation only with the truck at rest, its lens
within `align_tolerance` of one of the station's stop markers (the n-th stop marker lines up
the truck's n-th conveyor), the station asked for, a conveyor_command fresher than
`conveyor_timeout` (the conveyor drives' own watchdog: a dead load-handling processor cannot
leave a conveyor running), and a load to move and room for it.
"""

from collections.abc import Callable
import math
from typing import Any

from agv_nodes.world.layout import Layout, Marker
from agv_nodes.world.settings import WorldParams

LensPose = Callable[[], tuple[tuple[float, float], float]]  # (lens x, y), heading


class Conveyors:
    """See the module docstring."""

    def __init__(self, layout: Layout, p: WorldParams) -> None:
        self.layout, self.p = layout, p
        self.command: dict[str, Any] = {'first': 'off', 'second': 'off', 'station_request': 0}
        self.command_time = -1e9
        self.loads = [name in p.start_loaded for name in ('first', 'second')]
        self.station_loads = {sid: int(st.has_load) for sid, st in layout.stations.items()}
        self.transfer = 0.0  # fraction of the transfer in progress

    def on_command(self, fields: dict[str, Any], now: float) -> None:
        """Take a conveyor_command that arrived at sim time `now`."""
        self.command, self.command_time = dict(fields), now

    def aligned(self, at_rest: bool, lens_pose: LensPose) -> tuple[Marker, int] | None:
        """Return the stop marker (and truck conveyor index) the truck is aligned with, if any."""
        if not at_rest:
            return None
        lens, heading = lens_pose()
        fx, fy = math.cos(heading), math.sin(heading)
        for m in self.layout.markers:
            if m.kind != 'stop' or not m.station:
                continue
            dx, dy = lens[0] - m.centre[0], lens[1] - m.centre[1]
            along = dx * fx + dy * fy
            across = abs(-dx * fy + dy * fx) - m.standoff
            if abs(along) <= self.p.align_tolerance and abs(across) < 0.1:
                return m, m.identity
        return None

    def step(self, now: float, dt: float, at_rest: bool, lens_pose: LensPose) -> Marker | None:
        """Advance a transfer by `dt`; return the stop marker where a load has just moved."""
        cmd = self.command
        # The cheap tests first: the alignment (a pass over the markers) is pure.
        if now - self.command_time > self.p.conveyor_timeout or not cmd.get('station_request'):
            return None
        if (aligned := self.aligned(at_rest, lens_pose)) is None:
            return None
        marker, j = aligned
        action = cmd['first' if j == 0 else 'second']
        station = self.layout.stations[marker.station]
        if action == 'load' and self.station_loads[station.id] > 0 and not self.loads[j]:
            pass
        elif action == 'unload' and self.loads[j] and \
                self.station_loads[station.id] < station.capacity:
            pass
        else:
            return None
        self.transfer += self.p.conveyor_speed * dt / self.p.transfer_length
        if self.transfer < 1.0:
            return None
        self.transfer = 0.0
        if action == 'load':
            self.station_loads[station.id] -= 1
            self.loads[j] = True
        else:
            self.station_loads[station.id] += 1
            self.loads[j] = False
        return marker

    def status(self, at_rest: bool, lens_pose: LensPose) -> dict[str, int]:
        """Return the conveyor_status record."""
        aligned = self.aligned(at_rest, lens_pose)
        fields = {'load_first': int(self.loads[0]), 'load_second': int(self.loads[1]),
                  'station_aligned': 0, 'station_load': 0, 'station_full': 0,
                  'transfer': int(min(self.transfer, 1.0) * 100)}
        if aligned is not None:
            station = self.layout.stations[aligned[0].station]
            fields['station_aligned'] = 1
            fields['station_load'] = int(self.station_loads[station.id] > 0)
            fields['station_full'] = int(self.station_loads[station.id] >= station.capacity)
        return fields
