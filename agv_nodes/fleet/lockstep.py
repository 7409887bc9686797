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

`processes` > 1 steps the trucks in that many processes, forked once the trucks are built
(agv_nodes.fleet.truck_processes): the same samples in the same order, on more cores. Then
`trucks` holds only the trucks of this process (the first ones); `query` reaches any truck.
Close such a fleet (`close`, or use it as a context manager) to end its processes.

`add` puts a truck on the floor while the fleet runs and `remove` takes one off (a fleet
simulator's tester does: agv_nodes.fleet.fleet_sim). An added truck is powered on then: its
own clock starts at 0, as a truck's cores count from their start.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from agv_nodes.fleet.truck_processes import (
    TruckProcess,
    bump,
    load_changes,
    merge_load_changes,
)
from agv_nodes.harness import Harness, run_for, submit, truck
from agv_nodes.world.contact import Collision, ContactWatch, Pose
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.settings import ElectrukParams

__all__ = ['Collision', 'Fleet']

NOTES_KEPT = 500  # a far truck's notes not yet taken, as many as its core keeps (Notes)


def _reports(h: Harness) -> list[str]:
    return h.cores['communications'].notes.texts()


def shares(n: int, processes: int) -> list[int]:
    """Return how many of `n` trucks each process steps, the first process's first.

    The first process also checks the contacts and runs any master: it gets the fewest.
    """
    processes = max(1, min(processes, n))
    return sorted(n // processes + (k < n % processes) for k in range(processes))


class Fleet:
    """N trucks in lock step on one layout; see the module docstring."""

    def __init__(self, layout_name: str, starts: Sequence[tuple[str, float]], *, seed: int = 1,
                 names: Sequence[str] | None = None,
                 overrides: dict[str, dict[str, Any]] | None = None,
                 processes: int = 1) -> None:
        layout = load_layout(layout_path(layout_name))
        if layout.vehicle != 'electruk' or layout.kind != 'wire':
            raise LayoutError(f'{layout.file}: a fleet runs on a wire layout of the Electruk')
        self.names = list(names or (f'agv{k + 1}' for k in range(len(starts))))
        if len(self.names) != len(starts):
            raise ValueError(f'{len(starts)} starts for {len(self.names)} trucks')
        if processes < 1:
            raise ValueError(f'processes: {processes!r} must be >= 1')
        loads = {sid: int(st.has_load) for sid, st in layout.stations.items()}
        self.trucks: dict[str, Harness] = {
            name: truck(layout_name, seed=seed + k, start=start, station_loads=loads,
                        overrides=overrides)
            for k, (name, start) in enumerate(zip(self.names, starts, strict=True))}
        self.station_loads = loads
        self.contacts = ContactWatch(self.names)
        self.collisions: list[Collision] = self.contacts.collisions
        # a far truck's body: its outline, and its pose as its process last answered
        self._far: dict[str, tuple[Pose, ElectrukParams]] = {}
        if touching := self.contacts.contacts(self._bodies()):
            raise ValueError(f'trucks {sorted(touching)[0]} touch at the start: place them '
                             'further apart')
        self._workers: list[TruckProcess] = []
        self._owner: dict[str, TruckProcess] = {}
        self._notes: dict[str, deque[str]] = {}
        counts = shares(len(self.names), processes)
        local, first = self.names[:counts[0]], counts[0]  # the first process's: the first trucks
        for count in counts[1:]:
            theirs = self.names[first:first + count]
            first += count
            worker = TruckProcess({n: self.trucks[n] for n in theirs}, loads)
            self._workers.append(worker)
            for name in theirs:
                self._owner[name] = worker
                self._notes[name] = deque(maxlen=NOTES_KEPT)
                h = self.trucks.pop(name)  # stepped there from now on
                self._far[name] = (h.world.pose(), h.world.p.electruk)
        self._local = local
        self._closed = False
        self.layout_name, self.overrides = layout_name, overrides
        # the floor's clock: samples stepped, of the first truck's world (trucks come and go)
        self._samples, self._dt = 0, next(iter(self.trucks.values())).world.dt

    def __enter__(self) -> Fleet:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """End the fleet's other processes (none with `processes` 1); it steps no more."""
        for worker in self._workers:
            worker.close()
        self._workers = []
        self._closed = bool(self._owner)

    @property
    def now(self) -> float:
        """Simulated seconds (the same for every truck that was there from the start)."""
        return self._samples * self._dt  # as WorldCore.time counts them

    def submit(self, name: str, text: str) -> None:
        """Hand a task to truck `name`'s communications (a comms/task message in the graph)."""
        if (worker := self._owner.get(name)) is not None:
            worker.pending.append(('submit', name, text))  # at this time, before its next sample
        else:
            submit(self.trucks[name], text)

    def take_notes(self, name: str) -> list[str]:
        """Return the texts truck `name`'s communications wrote since the last take."""
        if (kept := self._notes.get(name)) is not None:
            out = list(kept)
            kept.clear()
            return out
        return [n.text for n in self.trucks[name].cores['communications'].notes.take()]

    def query(self, name: str, fn: Callable[..., Any], *args: Any) -> Any:
        """Return fn(truck `name`'s harness, *args), in the process that steps it.

        With more than one process `fn` must pickle (a module's function) and so must what it
        returns; what it changes of a far truck stays in that truck's process.
        """
        if (worker := self._owner.get(name)) is not None:
            return worker.query(name, fn, *args)
        return fn(self.trucks[name], *args)

    def _bodies(self) -> dict[str, tuple[Pose, ElectrukParams]]:
        far = self._far
        return {name: far[name] if name in far else
                (self.trucks[name].world.pose(), self.trucks[name].world.p.electruk)
                for name in self.names}

    def step(self) -> None:
        """One world sample for every truck, then the contacts between them."""
        self.step_trucks()
        self.check_contacts()

    def step_trucks(self) -> None:
        """One world sample for every truck (in its own process)."""
        self._samples += 1
        workers = self._workers
        if not workers:
            if self._closed:
                raise RuntimeError('fleet: closed, its other processes ended')
            for h in self.trucks.values():
                h.step()
            return
        for worker in workers:
            worker.send(('step',))
        loads = self.station_loads
        before = dict(loads)
        for h in self.trucks.values():
            h.step()
        changes = [load_changes(before, loads)]
        far = self._far
        for worker in workers:
            poses, notes, changed = worker.answer()
            for name, pose in zip(worker.names, poses, strict=True):
                far[name] = (pose, far[name][1])
            for name, texts in notes.items():
                self._notes[name].extend(texts)
            changes.append(changed)
        if any(changes[1:]):
            merged = merge_load_changes(changes, self.now)
            loads.update(merged)
            for worker, changed in zip(workers, changes[1:], strict=True):
                if others := {s: n for s, n in merged.items() if s not in changed}:
                    worker.pending.append(('loads', others))
        elif changes[0]:
            for worker in workers:
                worker.pending.append(('loads', changes[0]))

    def check_contacts(self) -> None:
        """Find new contacts between the bodies; bump both trucks of each."""
        for collision in self.contacts.check(self._bodies(), self.now):
            for name in collision.trucks:
                if (worker := self._owner.get(name)) is not None:
                    worker.pending.append(('bump', name))  # before its next sample
                else:
                    bump(self.trucks[name])

    def run(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        """Step for `seconds` of simulated time, or until `until()` is true (returns it)."""
        return run_for(self, seconds, until)

    def add(self, name: str, start: tuple[str, float], *, seed: int) -> None:
        """Put truck `name` on the floor at `start` (path, at), stepped from the next sample.

        It goes to the process that steps the fewest trucks (the others before the first, which
        also checks the contacts). ValueError when the name is taken or its body would touch
        another truck's.
        """
        if name in self.names:
            raise ValueError(f'truck {name!r} is on the floor already')
        h = truck(self.layout_name, seed=seed, start=start, station_loads=self.station_loads,
                  overrides=self.overrides)
        body = (h.world.pose(), h.world.p.electruk)
        watch = ContactWatch([*self.names, name])
        if touching := [pair for pair in watch.contacts({**self._bodies(), name: body})
                        if name in pair]:
            raise ValueError(f'truck {name!r} would touch {sorted(touching)[0]} at {start}')
        worker = min(self._workers, key=lambda w: len(w.names), default=None)
        if worker is None or len(worker.names) > len(self._local):
            self.trucks[name] = h
            self._local.append(name)
        else:  # built again there, from the same seed and loads: the same truck
            worker.pending.append(('add', name, self.layout_name, seed, start, self.overrides))
            worker.names.append(name)
            self._owner[name] = worker
            self._notes[name] = deque(maxlen=NOTES_KEPT)
            self._far[name] = body
        self.names.append(name)
        self.contacts.names.append(name)

    def remove(self, name: str) -> None:
        """Take truck `name` off the floor: from the next sample it is stepped no more."""
        if name not in self.names:
            raise KeyError(f'no truck {name!r} on the floor')
        self.names.remove(name)
        self.contacts.names.remove(name)
        self.contacts.touching = {pair for pair in self.contacts.touching if name not in pair}
        if (worker := self._owner.pop(name, None)) is not None:
            worker.pending.append(('remove', name))
            worker.names.remove(name)
            del self._far[name], self._notes[name]
        else:
            del self.trucks[name]
            self._local.remove(name)

    def reports(self, name: str) -> list[str]:
        """Return truck `name`'s communications reports so far."""
        return self.query(name, _reports)
