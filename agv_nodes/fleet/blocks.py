"""Traffic control for trucks sharing a track graph: blocks of nodes reserved one truck at a time.

A block is a named set of graph nodes (openTCS blocks, Open-RMF mutex groups); an edge belongs
to the block of its end node, so a truck driving an edge is in the block it drives into. A
block is held by at most one truck. The dispatcher releases a truck's order only through blocks
granted to it, so two trucks are never in one block.

Default blocks: each location marker with the stop markers that follow it before the next
location marker (demo_1983: {L0, W0.1}, {L2, W2.1, W2.2}, {L1, W1.1}, {L3, W3.1}). On a
one-way loop every way from one block leads into the next block of the ring, and every block
has a stop marker a truck can stand at: those two facts are what the grant policy's freedom
from deadlock rests on (see agv_nodes.fleet.dispatcher).

Grants are all-or-nothing, so a truck never holds half a corridor. A refused grant is recorded
as a wait for the trucks holding the blocks, and the wait-for graph's cycles are deadlocks: the
watchdog a dispatcher falls back on when its policy is not enough (another layout, a truck
that failed in the way).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import pairwise

from agv_nodes.fleet.track_graph import TrackGraph
from agv_nodes.world.settings import WorldParams


def truck_length(world: WorldParams | None = None) -> float:
    """Return the Electruk's length in m, bumper to bumper, from the world's figures.

    The whole length is how far behind its last marker a truck's tail may be: conservative,
    as its card reader is not behind its rear bumper.
    """
    e = (world or WorldParams()).electruk
    return e.rear_overhang + e.wheelbase + e.front_overhang


TRUCK_LENGTH = truck_length()  # 1.8 m


@dataclass(frozen=True)
class Block:
    """A named set of graph nodes that at most one truck may be in."""

    name: str
    nodes: frozenset[str]


def default_blocks(graph: TrackGraph) -> list[Block]:
    """Return a block per location marker with the stop markers following it on its wire."""
    blocks: dict[str, set[str]] = {}
    for node in graph.nodes.values():
        blocks.setdefault(node.location_marker or f'L{node.location}', set()).add(node.id)
    return [Block(name, frozenset(ids)) for name, ids in blocks.items()]


class Reservations:
    """Which truck holds which block, and who waits for whom."""

    def __init__(self, graph: TrackGraph, blocks: list[Block] | None = None) -> None:
        self.graph = graph
        self.blocks = {b.name: b for b in (blocks or default_blocks(graph))}
        self._of: dict[str, str] = {}
        for block in self.blocks.values():
            for node in block.nodes:
                if node in self._of:
                    raise ValueError(f'node {node} is in blocks {self._of[node]} and '
                                     f'{block.name}')
                self._of[node] = block.name
        missing = set(graph.nodes) - set(self._of)
        if missing:
            raise ValueError(f'nodes in no block: {sorted(missing)}')
        self._holder: dict[str, str] = {}  # block -> truck
        self._waits: dict[str, set[str]] = {}  # truck -> blocks it waits for

    # -- blocks of nodes and ways ----------------------------------------------------------
    def block_of(self, node: str) -> str:
        """Return the name of the block `node` is in (an edge's: its end node's)."""
        return self._of[node]

    def blocks_of(self, nodes: Iterable[str]) -> list[str]:
        """Return the blocks of `nodes` in the order the nodes first enter them."""
        out: list[str] = []
        for node in nodes:
            name = self._of[node]
            if name not in out:
                out.append(name)
        return out

    def footprint(self, trail: list[str], length: float = TRUCK_LENGTH) -> set[str]:
        """Return the blocks a truck whose last node is trail[-1] may still reach into.

        `trail` is the way it came, node by node. The tail is `length` behind the last node
        (at least: the truck is at or past it), on the edge into the first node of the trail
        less than `length` behind; the blocks from that edge's on are kept. A trail too short
        to hold the tail keeps the block of its first node, the conservative guess.
        """
        if not trail:
            return set()
        keep = {self._of[trail[-1]]}
        behind = 0.0
        for a, b in pairwise(reversed(trail)):  # b before a on the way
            edge = self.graph.edge(b, a)
            if edge is None:
                break
            behind += edge.length
            if behind >= length:
                break
            keep.add(self._of[b])
        return keep

    # -- holding ---------------------------------------------------------------------------
    def holder(self, block: str) -> str | None:
        """Return the truck holding `block`, or None when it is free."""
        return self._holder.get(block)

    def held(self, truck: str) -> set[str]:
        """Return the blocks `truck` holds."""
        return {b for b, t in self._holder.items() if t == truck}

    def free(self, blocks: Iterable[str], truck: str | None = None) -> bool:
        """Return True when each of `blocks` is free, or held by `truck` already."""
        return all(self._holder.get(b) in (None, truck) for b in blocks)

    def corridor(self, truck: str, path: list[str], start: int, end: int) -> list[str] | None:
        """Return the blocks to grant `truck` for path[start+1..end], all at once or none.

        The blocks the way enters after leaving the one of path[start] must all be free, or
        the corridor is None: a block the truck holds is one it is yet to leave (a lap), and
        holding it on would keep others out of it for the whole way round.
        """
        here = self._of[path[start]]
        blocks: list[str] = []
        left = False
        for node in path[start + 1:end + 1]:
            block = self._of[node]
            left = left or block != here
            if left and block not in blocks:
                if self._holder.get(block) == truck:
                    return None
                blocks.append(block)
        return blocks

    def grant(self, truck: str, blocks: Iterable[str], *, wait: bool = True) -> bool:
        """Grant all of `blocks` to `truck`, or none; a refusal is recorded as a wait.

        A block the truck holds already counts as granted. With `wait` False a refusal is
        not recorded (the truck has not run out of granted way yet).
        """
        wanted = list(blocks)
        if any(self._holder.get(b) not in (None, truck) for b in wanted):
            if wait:
                self.wait(truck, wanted)
            return False
        for b in wanted:
            self._holder[b] = truck
        self._waits.pop(truck, None)
        return True

    def occupy(self, truck: str, block: str) -> str | None:
        """Hold the block a truck is physically in; return the other holder, if any.

        A truck stands where it stands: this records it even against another holder (that
        truck's grant is wrong, and the caller is told who it is).
        """
        other = self._holder.get(block)
        self._holder[block] = truck
        return other if other not in (None, truck) else None

    def release(self, truck: str, blocks: Iterable[str]) -> list[str]:
        """Release those of `blocks` that `truck` holds; return them."""
        out = [b for b in blocks if self._holder.get(b) == truck]
        for b in out:
            del self._holder[b]
        return out

    def keep_only(self, truck: str, keep: Iterable[str]) -> list[str]:
        """Release every block of `truck` not in `keep`; return the released ones."""
        wanted = set(keep)
        return self.release(truck, [b for b in self.held(truck) if b not in wanted])

    # -- waiting and the deadlock watchdog ---------------------------------------------------
    def wait(self, truck: str, blocks: Iterable[str]) -> None:
        """Record that `truck` waits for those of `blocks` other trucks hold."""
        taken = {b for b in blocks if self._holder.get(b) not in (None, truck)}
        if taken:
            self._waits[truck] = taken
        else:
            self._waits.pop(truck, None)

    def stop_waiting(self, truck: str) -> None:
        """Forget that `truck` waits (it was granted another way, or has nothing to do)."""
        self._waits.pop(truck, None)

    def waiting(self, truck: str) -> set[str]:
        """Return the blocks `truck` waits for (empty: it does not wait)."""
        return set(self._waits.get(truck, ()))

    def wait_for(self) -> dict[str, set[str]]:
        """Return the wait-for graph: each waiting truck -> the trucks holding its blocks."""
        graph: dict[str, set[str]] = {}
        for truck, blocks in self._waits.items():
            holders = {self._holder[b] for b in blocks if self._holder.get(b) not in (None,
                                                                                     truck)}
            if holders:
                graph[truck] = holders
        return graph

    def deadlocks(self) -> list[list[str]]:
        """Return the cycles of the wait-for graph, each as its trucks from the smallest name.

        Each cycle is one deadlock: none of its trucks can go on until one of them is sent
        elsewhere (cancelled and re-routed).
        """
        graph = self.wait_for()
        cycles: list[list[str]] = []
        seen: set[tuple[str, ...]] = set()
        for start in sorted(graph):
            stack = [(start, [start])]
            while stack:
                here, path = stack.pop()
                for nxt in sorted(graph.get(here, ())):
                    if nxt == start:
                        key = tuple(sorted(path))
                        if key not in seen:
                            seen.add(key)
                            cycles.append(list(path))
                    elif nxt not in path and nxt > start:
                        stack.append((nxt, [*path, nxt]))
        return cycles
