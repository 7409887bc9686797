"""The records each agv-fleet-sim truck's bridge reads, tapped where the truck is stepped.

The vda5050_bridge node reads four of its truck's records as one more reader
(agv_nodes.vda5050.truck_records.RECORDS: the cards read, the loads, traction's stops, the
wheel counters), so its state carries lastNodeId from the cards, agvPosition dead-reckoned
since, `loads`, `safetyState` and `operatingMode`. A fleet-sim truck's bridge reads the same
records of its lock-step truck (the 16 bytes each, with their E2E counter and CRC) through
the same RecordTap, so a fault shows in its state as it would on the ROS bridge.

A truck may be stepped in another process (agv_nodes.fleet.truck_processes). There a
RecordBuffer on the truck's harness keeps what the truck wrote of RECORDS, and `take`, run in
that process by Fleet.query, hands over every tapped truck's records of that process at once:
one round trip per process and slice, not one per truck. Buffers are registered per simulator
(`owner`), so a simulator's leftovers never reach another one's trucks in the same process.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from agv_nodes.harness import Harness
from agv_nodes.vda5050.truck_records import RECORDS

Tapped = list[tuple[str, bytes, float]]  # (record, its 16 bytes, sim s on the truck's clock)

_BUFFERS: dict[str, dict[str, RecordBuffer]] = {}  # owner -> truck -> its buffer, this process


class RecordBuffer:
    """A harness tap keeping the records of RECORDS until they are taken."""

    def __init__(self) -> None:
        self.kept: Tapped = []

    def __call__(self, record: str, raw: bytes, now: float) -> None:
        """Keep one record the harness delivers, if the bridge reads it."""
        if record in RECORDS:
            self.kept.append((record, raw, now))

    def take(self) -> Tapped:
        """Return the records kept since the last take, and forget them."""
        kept, self.kept = self.kept, []
        return kept


def tap(h: Harness, owner: str, truck: str) -> None:
    """Put a RecordBuffer on truck `truck`'s harness `h` (run where the truck is stepped)."""
    buffer = RecordBuffer()
    h.taps.append(buffer)
    _BUFFERS.setdefault(owner, {})[truck] = buffer


def untap(h: Harness, owner: str, truck: str) -> None:
    """Take truck `truck`'s buffer off its harness `h`, with the records it kept."""
    buffer = _BUFFERS.get(owner, {}).pop(truck, None)
    if buffer is not None and buffer in h.taps:
        h.taps.remove(buffer)


def take(_h: Harness, owner: str) -> dict[str, Tapped]:
    """Return every tapped truck's records of this process (the process stepping `_h`).

    Each truck of `owner` tapped here is named, an empty list if it wrote none.
    """
    return {truck: buffer.take() for truck, buffer in _BUFFERS.get(owner, {}).items()}


def forget(owner: str) -> None:
    """Drop this process's buffers of `owner` (its simulator has closed)."""
    _BUFFERS.pop(owner, None)


def take_all(query: Callable[..., Any], trucks: list[str], owner: str) -> dict[str, Tapped]:
    """Return the records of every truck in `trucks`, one `query` per process stepping them.

    `query(truck, fn, *args)` is Fleet.query: it runs fn on the process stepping `truck`.
    """
    got: dict[str, Tapped] = {}
    for truck in trucks:
        if truck not in got:
            got.update(query(truck, take, owner))
    return got
