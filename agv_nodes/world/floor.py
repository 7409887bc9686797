"""Several trucks on one floor, over DDS: the world process simulates them all.

With the world's `trucks` parameter set ([agv1, agv2, ...]) the world node in the root namespace
is the floor: it makes one world node per truck, named `world` in that truck's namespace, so each
truck's graph (its seven nodes, namespaced) sees a world of its own, topic for topic. All are in
one process and step on one clock, which the floor publishes on /clock. What makes them one floor
is what the lock-step fleet (agv_nodes.fleet.lockstep) has: the stations' loads are one set, and
after every sample the floor checks each pair of footprints (agv_nodes.world.contact); trucks that
touch have collided, and each truck's world reports a `collision` event and presses its bumper,
which cuts the drive (WorldCore.bump). A collision is a failure of traffic control, never silent:
the floor logs it as an error as well.

Each truck is set down at a stop marker: the world's `set_down`, else the layout's `parking`
places in order. Its sensors are seeded with the world's seed plus its index, so their noise
differs from truck to truck.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
import re
from typing import TYPE_CHECKING, Any

from agv_nodes.params import parameter_error
from agv_nodes.world.contact import ContactWatch, Pose
from agv_nodes.world.settings import ElectrukParams, WorldNodeSettings, WorldParams

if TYPE_CHECKING:  # the node module builds floors
    from agv_nodes.world.node import WorldNode

TRUCK_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*\Z')  # one ROS namespace level


@dataclass
class Control:
    """Pause and single steps: one for the whole floor, whichever node's service is called."""

    paused: bool = False
    step_requests: int = 0


@dataclass
class Place:
    """A truck of a floor: its index, where it is set down, and what it shares with the rest."""

    index: int
    set_down: str  # a stop marker
    station_loads: dict[str, int]
    clock_pub: Any  # the floor's /clock writer
    control: Control


def set_down(node: WorldNode, s: WorldNodeSettings, place: Place | None
             ) -> tuple[str, float] | None:
    """Return (path, at) of the stop marker the truck is set down at; None: the layout's start.

    A truck of a floor is set down where its place says; one truck alone at `set_down`'s one
    entry when it names one.
    """
    name = place.set_down if place is not None else (s.set_down[0] if s.set_down else '')
    if not name:
        return None
    if place is None and len(s.set_down) > 1:
        raise parameter_error(node, 'set_down', list(s.set_down),
                              'one truck is set down at one stop marker (trucks is empty)')
    markers = {m.name: m for m in node.layout.markers if m.kind == 'stop'}
    if name not in markers:
        raise parameter_error(node, 'set_down', list(s.set_down) or name,
                              f'{name!r} is no stop marker of layout {node.layout.name} '
                              f'({", ".join(markers)})')
    return markers[name].path, markers[name].at


class Floor:
    """The trucks of one floor and the contacts between them (see the module docstring)."""

    def __init__(self, root: Any, s: WorldNodeSettings, wp: WorldParams,
                 make: Callable[[str, Place], Any]) -> None:
        self.root = root
        names = list(s.trucks)
        for name in names:
            if not TRUCK_NAME.match(name) or names.count(name) > 1:
                raise parameter_error(root, 'trucks', names,
                                      f'{name!r} is not a namespace name ([A-Za-z][A-Za-z0-9_]*) '
                                      'or is named twice')
        places = list(s.set_down) or list(root.layout.parking)
        if len(places) < len(names) or s.set_down and len(places) != len(names):
            given = 'set_down' if s.set_down else f'layout {root.layout.name} parking'
            key, value = ('set_down', list(s.set_down)) if s.set_down else ('trucks', names)
            raise parameter_error(root, key, value,
                                  f'{len(names)} trucks need a stop marker each; the {given} '
                                  f'names {len(places)} ({", ".join(places) or "none"})')
        loads = {sid: int(st.has_load) for sid, st in root.layout.stations.items()}
        self.names = names
        self.members = [make(f'/{name}', Place(k, places[k], loads, root.clock_pub,
                                                root.control))
                        for k, name in enumerate(names)]
        self.watch = ContactWatch(names)
        if touching := self.watch.contacts(self._bodies()):
            a, b = sorted(touching)[0]
            raise parameter_error(root, 'set_down', places[:len(names)],
                                  f'trucks {a} and {b} touch where they are set down')

    def _bodies(self) -> dict[str, tuple[Pose, ElectrukParams]]:
        return {name: (m.core.pose(), m.core.p.electruk)
                for name, m in zip(self.names, self.members, strict=True)}

    def contacts(self) -> None:
        """After a sample: a truck that touches another has collided (event, bumper)."""
        now = self.members[0].core.time
        for collision in self.watch.check(self._bodies(), now):
            a, b = collision.trucks
            self.root.get_logger().error(
                f'collision at {now:.3f} s: {a} ({collision.speeds[0]:.2f} m/s) and {b} '
                f'({collision.speeds[1]:.2f} m/s) touched')
            for name in collision.trucks:
                m = self.members[self.names.index(name)]
                before = len(m.core.events)
                m.core.bump()
                m.publish_events(m.core.events[before:])
