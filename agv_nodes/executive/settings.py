"""Executive settings: every parameter of the executive node, its default and its meaning."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from agv_nodes.settings import setting


def parse_srm_map(entries: Iterable[str]) -> dict[int, int]:
    """('1:15', '3:15') -> {1: 15, 3: 15} (location: SRM angle in degrees, + = left).

    ValueError names the first entry that is not location:angle, 0-31 and -45..45.
    """
    out = {}
    for entry in entries:
        location, _, angle = entry.partition(':')
        try:
            loc, ang = int(location), int(angle)
        except ValueError:
            raise ValueError(entry) from None
        if not (0 <= loc <= 31 and -45 <= ang <= 45):
            raise ValueError(entry)
        out[loc] = ang
    return out


@dataclass
class ExecutiveParams:
    """Tasks into sub-system commands, the route map, and the supervision of the truck."""

    period: float = setting(0.050, 'seconds between passes of the executive loop (and its '
                            'command records)', lo=0.01, hi=1.0)
    cruise_demand: int = setting(55, 'cruise, % armature duty (55 ~ 0.7 m/s, the practical top '
                                 'speed, thesis 7.2)', lo=6, hi=80)
    srm_demand: int = setting(27, 'wire changes, % armature duty (27 ~ 0.3 m/s, thesis 6.2)',
                              lo=6, hi=80)
    srm_map: tuple[str, ...] = setting((), 'route map: location:angle entries (location 0-31, '
                                       'SRM angle -45..45 degrees, + = left) where the route '
                                       'leaves the wire by an SRM (demo_1983: 1:15, 3:15)')
    # 150 ms = three 50 ms status heartbeats: the executive supervises on every record it
    # receives and traction cuts the armature when the 00H arrives, so the e-stop reaches the
    # drive within ~180 ms of a sub-system going silent (measured 106-179 ms), inside the
    # 200 ms the fault tests allow.
    status_timeout: float = setting(0.150, 'a status record older than this is a fault, s',
                                    lo=0.05, hi=10.0)
    # Six records of the other sub-systems (60 Hz together) take 100 ms, within status_timeout,
    # so on a healthy executive the count never delays a stale status.
    stale_confirm: int = setting(6, 'records from the other sub-systems that must arrive after '
                                 'a status before its age alone makes it stale (at twice '
                                 'status_timeout age alone does)', lo=0, hi=1000)
    reject_limit: int = setting(5, 'rejected records per second tolerated before it is a fault',
                                lo=0, hi=10000)
    route_limit: float = setting(80.0, 'metres travelled within one step before the route is '
                                 'declared overrun', lo=1.0, hi=10000.0)
    positioning_limit: float = setting(4.0, 'metres of positioning without reaching the stop '
                                       'marker before it is a fault', lo=0.5, hi=100.0)
    load_timeout: int = setting(20, 'seconds per load transfer (passed to load handling)',
                                lo=1, hi=255)
    trip_grace: float = setting(1.0, 'seconds after a task starts before a traction trip '
                                'counts as a fault', lo=0.0, hi=10.0)
    rest_speed: int = setting(3, 'below this traction_status speed, mm/s, the truck is at rest',
                              lo=0, hi=100)
    rest_time: float = setting(0.3, 'seconds at rest before a stop is complete', lo=0.0,
                               hi=5.0)
    speed_request_path: str = setting('direct_link', "forward navigation's speed request "
                                      '(via_executive), or let the direct link carry it',
                                      choices=('direct_link', 'via_executive'))
    # A departure from the 1983 receiver-side monostables (thesis 6.3), off by default: under
    # sim time `sent` ages a status from when it was sent, not from when a starved executive
    # got round to it (agv_nodes.sent_time). It needs /clock and one wall clock for the graph.
    status_age: str = setting('arrival', 'age of a status record: from its arrival here '
                              '(1983) or, under sim time, from when it was sent (a starved '
                              'executive blames nobody)', choices=('arrival', 'sent'))

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks `build` needs beyond each field's own: the route map's entries."""
        try:
            parse_srm_map(self.srm_map)
        except ValueError as exc:
            return [('srm_map', list(self.srm_map), f'entry {exc.args[0]!r} is not '
                     'location:angle with location 0-31 and angle -45..45')]
        return []
