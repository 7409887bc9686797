"""The dispatcher's settings: its parameters.yaml section, and the truck:node entries it takes.

ROS-free, so the dispatcher's core takes its defaults from the same place as its node
(agv_nodes.fleet.dispatcher_node) declares them.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import Any

from agv_nodes.settings import SettingError, settings_class
from agv_nodes.vda5050.topics import topic


def truck_map(name: str, entries: Sequence[str], trucks: Sequence[str],
              stops: Collection[str] | None = None) -> dict[str, str]:
    """Return the `truck:node` entries of parameter `name` as {truck: node}.

    Each truck must be one of `trucks` and named once; with `stops` given, each node must be
    one of them (the stop markers: where a truck can stand). SettingError names the entry.
    """
    out: dict[str, str] = {}
    for entry in entries:
        truck, sep, node = entry.partition(':')
        if not sep or not truck or not node or ' ' in entry:
            raise SettingError(name, entry, "not truck:stop-marker, e.g. 'agv1:W0.1'")
        if truck not in trucks:
            raise SettingError(name, entry, f'{truck!r} is not one of trucks {list(trucks)}')
        if truck in out:
            raise SettingError(name, entry, f'{truck!r} given twice')
        if stops is not None and node not in stops:
            raise SettingError(name, entry, f'{node!r} is no stop marker of the layout '
                               f'(stop markers: {", ".join(sorted(stops))})')
        out[truck] = node
    return out


@settings_class
class DispatcherSettings:
    """The fleet's central computer as a VDA 5050 master (its parameters.yaml section)."""

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks that span fields: trucks, and the entries naming them."""
        trucks: tuple[str, ...] = self.trucks  # type: ignore[attr-defined]
        manufacturer: str = self.manufacturer  # type: ignore[attr-defined]
        if not trucks:
            return [('trucks', [], 'needs at least one serial number')]
        # both are topic levels (VDA 5050 6.3): not empty, no '/', '+', '#' or '$'
        for name, value, levels in (('manufacturer', manufacturer, (manufacturer, 'x')),
                                    *(('trucks', list(trucks), ('x', t)) for t in trucks)):
            try:
                topic(*levels, 'state')
            except ValueError as exc:
                return [(name, value, str(exc))]
        for truck in trucks:
            if trucks.count(truck) > 1:
                return [('trucks', list(trucks), f'{truck!r} given twice')]
        for name in ('positions', 'parking'):
            try:
                truck_map(name, getattr(self, name), trucks)
            except SettingError as exc:
                return [(exc.name, exc.value, exc.reason)]
        return []
