"""Pacing: the simulated world waits for the slowest node (ROS-free).

Nine Python processes share two cores; a node starved of CPU would see the truck move on without it
(a missed marker, a stop 30 mm late, steering on 100 ms old wire samples). Gazebo calls the remedy
lock-step: `GraphPacer` keeps each node's latest word on the simulation channel
(agv_nodes.sim_progress) and says which nodes lag by more than `max_lag` beyond the progress period
and the /clock step. The world waits for them (real time only) at most `lag_patience` real seconds,
then carries on: a node that died must not stop the world, the rest of the graph has to see the
truck stop. A node given up is waited for again once heard from (docs/architecture.md). Until a
node has been heard from since the world started moving, the world waits for it longer
(`start_patience`): the first seconds of a crowded machine (a fleet's nineteen processes still
settling their discovery) can hold every node back at once, and a world that carried on then
would leave them all behind.
"""

from dataclasses import dataclass, field

from agv_nodes import sim_progress


@dataclass
class GraphPacer:
    """Which nodes lag the world's clock, and by how much (`max_lag` 0: never wait)."""

    max_lag: float
    nodes: tuple[str, ...]
    clock_step: float = 0.0  # s between /clock messages: progress moves in these steps
    period: float = sim_progress.PERIOD  # s between a node's progress messages
    worst: dict[str, float] = field(default_factory=dict)  # node -> most s behind when heard
    _heard: dict[str, float | None] = field(default_factory=dict)
    _gave_up: set[str] = field(default_factory=set)
    _unheard: set[str] = field(default_factory=set)  # not heard from since start()

    def __post_init__(self) -> None:
        self._heard = dict.fromkeys(self.nodes)

    @property
    def allowance(self) -> float:
        """How far a node's last word may lag the world before the world waits, s."""
        return self.max_lag + self.period + self.clock_step

    def start(self, now: float) -> None:
        """Start the world at `now`; a node not heard yet counts as heard then (so waited for)."""
        for node, heard in self._heard.items():
            if heard is None:
                self._heard[node] = now
        self._unheard = set(self.nodes)

    def progress(self, node: str, handled: float, now: float) -> None:
        """`node` has handled everything up to sim time `handled`; the world is at `now`."""
        if node not in self._heard:
            return
        self._heard[node] = handled
        self._gave_up.discard(node)
        self._unheard.discard(node)
        self.worst[node] = max(self.worst.get(node, 0.0), now - handled)

    def behind(self, node: str, now: float) -> float:
        """How far `node` lags beyond its allowance: > 0 means the world should wait."""
        heard = self._heard.get(node)
        if heard is None or node in self._gave_up:
            return 0.0
        return (now - heard) - self.allowance

    def lagging(self, now: float) -> list[str]:
        """Nodes that have fallen behind the world."""
        return [node for node in self.nodes if self.max_lag and self.behind(node, now) > 0]

    def unheard(self, nodes: list[str]) -> list[str]:
        """Those of `nodes` not heard from since the world started moving."""
        return [node for node in nodes if node in self._unheard]

    def give_up(self, nodes: list[str]) -> None:
        """Stop waiting for `nodes` until they are heard from again."""
        self._gave_up.update(nodes)
