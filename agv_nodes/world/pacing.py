"""Pacing: the simulated world waits for the slowest record writer (ROS-free).

A simulation is only faithful if every node sees time pass as the truck does. On real hardware
the clock never waits; in the simulated graph nine Python processes share two cores, and a node
that is starved of CPU falls behind the world's clock: its sensor samples queue up, its commands
arrive late, and the truck it drives behaves as if the Z-80 had stalled (a missed marker, a
stop 30 mm late, a traction stale-command trip). Gazebo calls the remedy lock-step; here the
world keeps a `GraphPacer` that notes when each paced record last arrived, in sim time, and
before each step asks which writers lag by more than `max_lag` beyond their own period. The
world then waits (real time only: sim time does not move) until they catch up, or for
`lag_patience` real seconds, after which it carries on without them: a node that died must not
stop the world, since the rest of the graph has to see the truck stop.

A heartbeat says a node's timer ran, not that it has read its input. For the position sensor,
which consumes the world's 340 Hz ADC stream, the pacer also compares the sensor's own count of
snapshots processed (`position_sensor_status.sample_count`) with the world's count of snapshots
published. Samples lost on the way leave a permanent difference; the pacer accepts it when it
gives up waiting and counts it as `lost_samples`.

Route following is paced the same way on the guide-wire stream (`steering_command.wire_count`,
100 Hz). A node that is behind still sends a steering demand every tick, so its heartbeat never
lagged, but each demand came from samples 100-200 ms old (one full demo in four at 6.3x on
2026-11-24): past the steering loop's ~0.1 s delay margin (lock step, `Link(delay=...)` on
steering_command: stable at 80 ms, lost the wire at 120 ms), the truck snaked off the wire
at 0.7 m/s and the task failed `lost wire`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

COUNT_WRAP = 1 << 16  # position_sensor_status.sample_count is u16le


@dataclass
class _Paced:
    allowance: float            # s of sim time the record may be older than the world
    arrived: float | None = None  # sim time of its last arrival (None: not yet seen)
    gave_up: bool = False


@dataclass
class _Consumer:
    allowance: int                 # samples the reader may be behind when its record arrives
    rate: float                    # samples per second of the stream it consumes
    processed: int = 0             # samples it reports processed (unwrapped)
    last_count: int | None = None  # its last u16 count
    missing: int = 0               # world samples it had not processed when last heard from
    offset: int = 0                # samples accepted as lost


@dataclass
class GraphPacer:
    """Which paced writers lag the world's clock, and by how much.

    `periods` maps each paced record to its heartbeat period (s); `consumers` names the records
    whose count of world samples taken must keep up with the world's count, of a stream of
    `sample_rate` samples a second unless `consumer_rates` names another (the route follower's
    100 Hz guide_wire). `max_lag` = 0 disables pacing.
    """

    max_lag: float
    periods: dict[str, float]
    sample_rate: float
    clock_step: float = 0.0  # s between /clock messages: a sim-time timer fires up to this late
    consumers: tuple[str, ...] = ()
    consumer_rates: dict[str, float] = field(default_factory=dict)
    slack: dict[str, float] = field(default_factory=dict)  # extra allowance (injected faults)
    lost_samples: int = 0
    worst: dict[str, float] = field(default_factory=dict)  # consumer -> most s behind heard
    _paced: dict[str, _Paced] = field(default_factory=dict)
    _consumers: dict[str, _Consumer] = field(default_factory=dict)
    names: list[str] = field(init=False, default_factory=list)  # every paced record

    def __post_init__(self) -> None:
        for name, period in self.periods.items():
            self._paced[name] = _Paced(self.max_lag + period + self.clock_step
                                       + self.slack.get(name, 0.0))
        for name in self.consumers:  # measured on arrival, so its period does not count
            # (an injected delay, in `slack`, holds the count back as much as the heartbeat)
            rate = self.consumer_rates.get(name, self.sample_rate)
            allowance = self.max_lag + self.clock_step + self.slack.get(name, 0.0)
            self._consumers[name] = _Consumer(max(1, round(allowance * rate)), rate)
        self.names = sorted(set(self._paced) | set(self._consumers))


    def start(self, now: float) -> None:
        """The world starts moving at sim time `now`: every paced writer not heard from yet is
        taken as heard at `now`, so the world waits for its first record as for any other.

        Without it a writer was paced only from its first record on, and a node starved at
        start-up fell behind unwaited: in one full demo (6.3x) communications sent its first
        comms_status 2.75 s of sim time after the world moved, and the executive rightly
        reported it silent (`no status record received`) in `/diagnostics`. A writer that
        never comes is given up after `lag_patience` like a dead one.
        """
        for paced in self._paced.values():
            if paced.arrived is None:
                paced.arrived = now

    def arrived(self, name: str, now: float, sample_count: int | None = None,
                world_samples: int = 0) -> None:
        """Record `name` arrived at sim time `now` (a consumer's with its sample_count, when the
        world had published `world_samples`)."""
        paced = self._paced.get(name)
        if paced is not None:
            paced.arrived = now
            paced.gave_up = False
        consumer = self._consumers.get(name)
        if consumer is not None and sample_count is not None:
            if consumer.last_count is not None:
                consumer.processed += (sample_count - consumer.last_count) % COUNT_WRAP
            else:
                consumer.processed = sample_count
            consumer.last_count = sample_count
            consumer.missing = world_samples - consumer.processed - consumer.offset
            self.worst[name] = max(self.worst.get(name, 0.0), consumer.missing / consumer.rate)

    def behind(self, name: str, now: float) -> float:
        """How far `name` lags beyond its allowance: > 0 means the world should wait."""
        worst = 0.0
        paced = self._paced.get(name)
        if paced is not None and paced.arrived is not None and not paced.gave_up:
            worst = max(worst, (now - paced.arrived) - paced.allowance)
        consumer = self._consumers.get(name)
        if consumer is not None and consumer.last_count is not None:
            worst = max(worst, (consumer.missing - consumer.allowance) / consumer.rate)
        return worst

    def lagging(self, now: float) -> list[str]:
        """Paced records whose writers have fallen behind the world."""
        if not self.max_lag:
            return []
        return [name for name in self.names if self.behind(name, now) > 0]

    def give_up(self, names: list[str]) -> int:
        """Stop waiting for `names`; returns the samples accepted as lost by consumers.

        A silent writer is waited for again once it is heard from. A consumer that still
        reports too few samples after the wait lost them on the way (its reader queue
        overflowed or the transport dropped them): the shortfall beyond half its allowance is
        accepted and counted (an estimate, to within half the allowance).
        """
        lost = 0
        for name in names:
            if name in self._paced:
                self._paced[name].gave_up = True
            consumer = self._consumers.get(name)
            if consumer is not None and consumer.missing > consumer.allowance:
                accepted = consumer.missing - consumer.allowance // 2
                consumer.offset += accepted
                consumer.missing -= accepted
                lost += accepted
        self.lost_samples += lost
        return lost
