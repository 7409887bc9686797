"""Several 1983 trucks on one floor in lock step, without DDS: each a whole truck, one floor.

Each truck is the lock-step harness of one truck (agv_nodes.harness.truck: its world core and
its seven node cores), placed at its own start on the same layout. What makes it one floor:
the stations' loads are one set, shared by every truck's world (a load one truck takes is gone
for the others), and the trucks' bodies are solid. After every world sample the fleet checks
each pair of footprints (agv_nodes.world.contact); trucks that touch have collided: each
world reports a `collision` event and its bumper cuts the drive (WorldCore.bump). A collision
is a failure of traffic control and is never silent: `collisions` lists each one.

Every truck steps the same sample in turn, so all share one simulated clock; the seeds differ
per truck (seed + index), so their sensors' noise does too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from agv_nodes.harness import Harness, run_for, submit, truck
from agv_nodes.world.contact import Collision, ContactWatch
from agv_nodes.world.layout import LayoutError, layout_path, load_layout

__all__ = ['Collision', 'Fleet']


class Fleet:
    """N trucks in lock step on one layout; see the module docstring."""

    def __init__(self, layout_name: str, starts: Sequence[tuple[str, float]], *, seed: int = 1,
                 names: Sequence[str] | None = None,
                 overrides: dict[str, dict[str, Any]] | None = None) -> None:
        layout = load_layout(layout_path(layout_name))
        if layout.vehicle != 'electruk' or layout.kind != 'wire':
            raise LayoutError(f'{layout.file}: a fleet runs on a wire layout of the Electruk')
        self.names = list(names or (f'agv{k + 1}' for k in range(len(starts))))
        if len(self.names) != len(starts):
            raise ValueError(f'{len(starts)} starts for {len(self.names)} trucks')
        loads = {sid: int(st.has_load) for sid, st in layout.stations.items()}
        self.trucks: dict[str, Harness] = {
            name: truck(layout_name, seed=seed + k, start=start, station_loads=loads,
                        overrides=overrides)
            for k, (name, start) in enumerate(zip(self.names, starts, strict=True))}
        self.station_loads = loads
        self.contacts = ContactWatch(self.names)
        self.collisions: list[Collision] = self.contacts.collisions
        if touching := self.contacts.contacts(self._bodies()):
            raise ValueError(f'trucks {sorted(touching)[0]} touch at the start: place them '
                             'further apart')

    @property
    def now(self) -> float:
        """Simulated seconds (the same for every truck)."""
        return next(iter(self.trucks.values())).now

    def submit(self, name: str, text: str) -> None:
        """Hand a task to truck `name`'s communications (a comms/task message in the graph)."""
        submit(self.trucks[name], text)

    def _bodies(self) -> dict[str, tuple[tuple[float, ...], Any]]:
        return {name: (h.world.pose(), h.world.p.electruk) for name, h in self.trucks.items()}

    def step(self) -> None:
        """One world sample for every truck, then the contacts between them."""
        for h in self.trucks.values():
            h.step()
        for collision in self.contacts.check(self._bodies(), self.now):
            for name in collision.trucks:
                h = self.trucks[name]
                before = len(h.world.events)
                h.world.bump()
                h.events.extend(h.world.events[before:])

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step for `seconds` of simulated time, or until `until()` is true (returns it)."""
        return run_for(self, seconds, until)

    def reports(self, name: str) -> list[str]:
        """Return truck `name`'s communications reports so far."""
        return self.trucks[name].cores['communications'].notes.texts()
