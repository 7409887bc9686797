"""A lock-step fleet's trucks stepped in more than one process: the same samples, on more cores.

A truck's lock-step harness (its world core and node cores) touches nothing of the other
trucks' within a sample but two things: the stations' loads (one set for the floor) and, after
the sample, the contact check between the bodies. So a fleet can fork processes that each
step some of its trucks, sample by sample, in lock step with the first:

- the first process sends each other one a `step`, steps its own trucks, then takes each
  one's answer: its trucks' poses, the notes their communications cores wrote (what a bridge
  reads), and the stations whose loads its trucks changed;
- what the first process decides after the sample (a bump where bodies touched, a task for a
  truck, another process's station loads) goes to a truck's process ahead of its next `step`,
  so the truck sees it at the same simulated time and in the same order as in one process.

The trucks are built before the fork, so each process holds the very state one process would.
What cannot be ordered as one process orders it is refused, not guessed: two processes that
change one station's load in the same sample (in one process the later truck would see the
earlier one's change; two trucks at one station at once have collided anyway) stop the run.

Each side waits for the other by polling a short while before it blocks: a sample takes a few
hundred microseconds, and a blocked process takes tens of microseconds to wake.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, MutableMapping, Sequence
import multiprocessing
from multiprocessing.connection import Connection
import time
import traceback
from typing import Any

from agv_nodes.harness import Harness, submit, truck

SPIN = 200e-6  # s a side polls for the other's message before it blocks

# ('loads', {station: load}) | ('submit', truck, text) | ('bump', truck) | ('remove', truck)
# | ('add', truck, layout, seed, start, overrides): a truck put on the floor (Fleet.add)
Op = tuple[Any, ...]


def bump(h: Harness) -> None:
    """Hit truck `h`'s bumper: its world cuts the drive and reports the collision."""
    before = len(h.world.events)
    h.world.bump()
    h.events.extend(h.world.events[before:])


def load_changes(before: Mapping[str, int], after: Mapping[str, int]) -> dict[str, int]:
    """Return the stations whose loads differ from `before`, with their loads now."""
    return {sid: n for sid, n in after.items() if before[sid] != n}


def merge_load_changes(changes: Sequence[Mapping[str, int]], now: float) -> dict[str, int]:
    """Return every process's station changes of one sample as one.

    A station changed by two processes is refused (see the module docstring).
    """
    merged: dict[str, int] = {}
    for changed in changes:
        for sid, n in changed.items():
            if sid in merged:
                raise RuntimeError(f'fleet processes: station {sid} changed by trucks of two '
                                   f'processes in the sample at {now:.4f} s')
            merged[sid] = n
    return merged


def receive(conn: Connection) -> Any:
    """Return the next message on `conn`, polling for SPIN seconds before blocking."""
    end = time.perf_counter() + SPIN
    while not conn.poll(0) and time.perf_counter() < end:
        pass
    return conn.recv()


def _apply(trucks: MutableMapping[str, Harness], loads: dict[str, int], ops: Sequence[Op]) -> None:
    for op in ops:
        if op[0] == 'loads':
            loads.update(op[1])
        elif op[0] == 'submit':
            submit(trucks[op[1]], op[2])
        elif op[0] == 'add':
            _, name, layout, seed, start, overrides = op
            trucks[name] = truck(layout, seed=seed, start=start, station_loads=loads,
                                 overrides=overrides)
        elif op[0] == 'remove':
            del trucks[op[1]]
        else:  # 'bump'
            bump(trucks[op[1]])


def _serve(conn: Connection, trucks: dict[str, Harness], loads: dict[str, int]) -> None:
    """Serve a fleet process: (ops, command) in, its answer out, until `close` or EOF."""
    try:
        while True:
            try:
                ops, command = receive(conn)
            except EOFError:  # the first process is gone
                return
            _apply(trucks, loads, ops)
            if command[0] == 'step':
                before = dict(loads)
                for h in trucks.values():
                    h.step()
                notes = {}
                for name, h in trucks.items():
                    if taken := h.cores['communications'].notes.take():
                        notes[name] = [n.text for n in taken]
                conn.send(('ok', ([h.world.pose() for h in trucks.values()], notes,
                                  load_changes(before, loads))))
            elif command[0] == 'query':
                _, name, fn, args = command
                conn.send(('ok', fn(trucks[name], *args)))
            else:  # 'close'
                conn.send(('ok', None))
                return
    except Exception:  # noqa: BLE001 - any failure goes back to the first process, named
        conn.send(('error', traceback.format_exc()))


class TruckProcess:
    """Some of a fleet's trucks, stepped in a forked process; see the module docstring."""

    def __init__(self, trucks: dict[str, Harness], loads: dict[str, int]) -> None:
        self.names = list(trucks)
        self.pending: list[Op] = []  # for the process ahead of its next command
        self._conn, child = multiprocessing.get_context('fork').Pipe()
        self._process = multiprocessing.get_context('fork').Process(
            target=_serve, args=(child, trucks, loads), daemon=True,
            name=f'fleet trucks {",".join(self.names)}')
        self._process.start()
        child.close()

    def send(self, command: tuple[Any, ...]) -> None:
        """Send the pending ops and `command`."""
        self._conn.send((self.pending, command))
        self.pending = []

    def answer(self) -> Any:
        """Return the answer to the last command; raise what failed in the process."""
        try:
            status, value = receive(self._conn)
        except (EOFError, OSError):  # the process ended, or this side was closed
            raise RuntimeError(f'fleet process of {", ".join(self.names)} ended') from None
        if status == 'error':
            raise RuntimeError(f'fleet process of {", ".join(self.names)} failed:\n{value}')
        return value

    def query(self, name: str, fn: Callable[..., Any], *args: Any) -> Any:
        """Return fn(truck `name`'s harness, *args), run in the process (fn: picklable)."""
        self.send(('query', name, fn, args))
        return self.answer()

    def close(self) -> None:
        """End the process (after the pending ops); it is joined."""
        if self._process.is_alive():
            try:
                self.send(('close',))
                self.answer()
            except (OSError, RuntimeError):
                pass
        self._process.join(timeout=5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._conn.close()
