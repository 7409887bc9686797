"""Traction's start-up contract (docs/hardware.md, "Starting a board"): every run starts.

A stand-in executive written from the contract's text (`contract_demand`) drives a real
TractionCore, set as the graph's traction is (config/agv_demo.yaml), through a model of the DDS
link that costs a board its start: whatever the stand-in sends before traction's reader has
matched its writer is lost (seeded match time), every record arrives a seeded latency late and in
order, and in some runs a corrupt command (a trip while tripped, which restarts the latch) falls
between the stand-in's 00H and its demand. The stand-in's first record and traction's loop have
seeded phases against each other. Periods come from msg_schemas/ (each record's `period_ms`).

The other half is the cause, kept as a test: the stand-in the outside testers wrote (00H for 1 s,
then its demand, never looking back) starts only when the reader matched within its 1 s of 00H.
"""

from __future__ import annotations

from collections.abc import Callable
import random

import pytest

from agv_nodes.package_share import config_dir
from agv_nodes.records.codec import codec
from agv_nodes.settings import settings_from_file
from agv_nodes.traction.core import TractionCore
from agv_nodes.traction.settings import TractionParams

COMMAND_MS = round(codec()['traction_command'].period_ms)  # the stand-in's rate
STATUS_MS = round(codec()['traction_status'].period_ms)  # what it hears back
DEMAND = 30  # % duty the stand-in wants once started
LATENCY_MS = (1, 20)  # one record's delivery, either way
RUNS = 20


def graph_traction() -> TractionCore:
    """Traction as the launched graph sets it (the parameter file, no overrides)."""
    return TractionCore(settings_from_file(TractionParams, config_dir() / 'agv_demo.yaml',
                                           'traction'))


def command(demand: int) -> dict[str, int]:
    """Return a traction_command in auto mode, executive priority (the Position link ignored)."""
    return {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': demand,
            'executive_priority': 1}


def contract_demand(status: dict | None, wanted: int) -> int:
    """Return the demand the contract's rule sends, from the last traction_status heard.

    00H until a status is heard; 00H while it says tripped without emergency_stop (the latch not
    armed: no 00H of ours taken since the trip); the wanted demand otherwise (armed: the next
    non-zero demand closes the relay; or running).
    """
    if status is None or (status['tripped'] and not status['emergency_stop']):
        return 0
    return wanted


def naive_demand(now_ms: int, first_ms: int) -> int:
    """Return what the outside testers' stand-in sent: 00H for 1 s, then its demand."""
    return 0 if now_ms < first_ms + 1000 else DEMAND


class Run:
    """One start: traction, the stand-in and the link between them, on a 1 ms clock."""

    def __init__(self, seed: int, feedback: bool = True, matched_ms: int | None = None,
                 corrupt: bool | None = None) -> None:
        rng = random.Random(seed)
        self.rng = rng
        self.core = graph_traction()
        self.loop_ms = round(self.core.p.loop_period * 1000)
        self.phase_ms = rng.randrange(self.loop_ms)  # traction's first pass
        self.first_ms = rng.randrange(0, 2000)  # the stand-in's first record
        self.matched_ms = rng.randrange(0, 2500) if matched_ms is None else matched_ms
        corrupt = rng.random() < 0.5 if corrupt is None else corrupt
        # a corrupt command in the handshake: up to 300 ms after the reader matched
        self.corrupt_ms = self.matched_ms + rng.randrange(0, 300) if corrupt else None
        self.feedback = feedback
        self.status: dict | None = None  # the last traction_status the stand-in heard
        self.to_traction: list[tuple[int, str, dict | None]] = []  # (at, what, fields)
        self.to_standin: list[tuple[int, dict]] = []
        self.delivered: list[tuple[int, int | None]] = []  # (ms, demand; None: corrupt)
        self.drive: list[tuple[int, int]] = []  # (ms, contactor)
        self.cleared_ms: int | None = None

    def _late(self, queue: list, sent_ms: int) -> int:
        """Arrival of a record sent now: a seeded latency, never before the one before it."""
        at = sent_ms + self.rng.randint(*LATENCY_MS)
        return max(at, queue[-1][0]) if queue else at

    def demand(self, now_ms: int) -> int:
        """Return the demand the stand-in sends now."""
        if self.feedback:
            return contract_demand(self.status, DEMAND)
        return naive_demand(now_ms, self.first_ms)

    def run(self, until_ms: int) -> None:
        """Step the 1 ms clock to `until_ms`."""
        core = self.core
        for now in range(until_ms):
            t = now / 1000
            if now >= self.first_ms and (now - self.first_ms) % COMMAND_MS == 0 \
                    and now >= self.matched_ms:  # sent before the match: lost
                self.to_traction.append((self._late(self.to_traction, now), 'record',
                                         command(self.demand(now))))
            elif now >= self.first_ms and (now - self.first_ms) % COMMAND_MS == 0:
                self.demand(now)  # sent, and lost on the way
            if now == self.corrupt_ms:
                self.to_traction.append((self._late(self.to_traction, now), 'corrupt', None))
            while self.to_traction and self.to_traction[0][0] <= now:
                _at, what, fields = self.to_traction.pop(0)
                if what == 'corrupt':
                    self.delivered.append((now, None))
                    core.on_reject('traction_command', 'bad_crc', t)
                else:
                    self.delivered.append((now, fields['demand']))
                    core.on_record('traction_command', fields, t)
            while self.to_standin and self.to_standin[0][0] <= now:
                self.status = self.to_standin.pop(0)[1]
            if now >= self.phase_ms and (now - self.phase_ms) % self.loop_ms == 0:
                out = core.tick(t)
                self.drive.append((now, out['traction_drive']['contactor']))
                if 'traction_status' in out:
                    self.to_standin.append((self._late(self.to_standin, now),
                                            out['traction_status']))
            if self.cleared_ms is None and not core.tripped:
                self.cleared_ms = now

    def allowed_from(self) -> int | None:
        """When the written rule first lets the relay close: a non-zero demand after a 00H.

        Counted from what traction was delivered, not from what it did; a corrupt command
        delivered before that demand restarts the rule (the latch), as the contract says.
        """
        seen_zero = False
        for at, d in self.delivered:
            if d is None:
                seen_zero = False
            elif d == 0:
                seen_zero = True
            elif seen_zero:
                return at
        return None


def bound_ms(run: Run) -> int:
    """Latest clearance the contract allows: from the match (or the corrupt record).

    One 00H out and in, a status out and in, the demand out and in; twice, for a trip that
    lands in the middle of it.
    """
    one = COMMAND_MS + STATUS_MS + COMMAND_MS + 3 * LATENCY_MS[1] + run.loop_ms
    start = max(run.first_ms, run.matched_ms, run.corrupt_ms or 0)
    return start + 2 * one


@pytest.mark.timeout(60)
def test_a_stand_in_that_follows_the_contract_starts_the_truck_in_every_run():
    runs = [Run(seed) for seed in range(RUNS)]
    for r in runs:
        r.run(bound_ms(r) + 1000)
    late = [(seed, r.cleared_ms, bound_ms(r), r.matched_ms, r.corrupt_ms)
            for seed, r in enumerate(runs) if r.cleared_ms is None or r.cleared_ms > bound_ms(r)]
    assert not late, f'(seed, cleared, bound, matched, corrupt): {late}'
    # the drive stays on after it: the stand-in's 50 ms keeps the command fresh
    assert all(not r.core.tripped for r in runs), [r.core.trip_cause for r in runs]
    # the phases really varied, and half the runs met a trip inside the handshake
    assert len({r.phase_ms for r in runs}) > 5 and len({r.first_ms for r in runs}) == RUNS
    assert 5 <= sum(r.corrupt_ms is not None for r in runs) <= 15


@pytest.mark.timeout(60)
def test_the_relay_never_closes_before_the_rule_allows():
    """Safety: no contactor before a non-zero demand that follows a 00H (latch restarted)."""
    for seed in range(RUNS):
        r = Run(seed)
        r.run(bound_ms(r) + 500)
        allowed = r.allowed_from()
        assert allowed is not None, seed
        early = [at for at, on in r.drive if on and at < allowed]
        assert not early, (seed, allowed, early[:3])


@pytest.mark.timeout(60)
@pytest.mark.parametrize('matched_ms, starts', [(0, True), (600, True), (1400, False),
                                                (2200, False)])
def test_without_the_status_a_late_match_leaves_the_truck_tripped(matched_ms, starts):
    """The cause: 00H for 1 s then the demand starts only if the reader matched in that second.

    The stand-in's first record is at a seeded time in 0-2 s; the match is put against it.
    """
    r = Run(3, feedback=False, corrupt=False)
    r.matched_ms = r.first_ms + matched_ms
    r.run(r.first_ms + 4000)
    assert (r.cleared_ms is not None) is starts, (r.first_ms, r.cleared_ms)
    if not starts:
        assert r.core.trip_cause == 'startup'
        assert r.delivered and {d for _at, d in r.delivered} == {DEMAND}


@pytest.mark.timeout(60)
def test_the_status_says_when_a_00h_was_taken():
    """Tripped: emergency_stop 0 until a 00H arrives, 1 after it; a trip while tripped clears it.

    Read from the status record's fields (msg_schemas/traction_status.yaml) as a board would.
    """
    core = graph_traction()
    statuses: list[dict] = []
    t = 0.0

    def run(seconds: float, send: Callable[[], dict | None]) -> None:
        nonlocal t
        end = t + seconds
        while t < end - 1e-9:
            if (fields := send()) is not None and round(t * 1000) % COMMAND_MS == 0:
                core.on_record('traction_command', fields, t)
            out = core.tick(t)
            if 'traction_status' in out:
                statuses.append(out['traction_status'])
            t = round(t + core.p.loop_period, 6)

    run(0.2, lambda: None)
    assert statuses[-1]['tripped'] == 1 and statuses[-1]['trip_cause'] == 'startup'
    assert statuses[-1]['emergency_stop'] == 0  # nothing taken yet
    run(0.1, lambda: command(0))
    assert statuses[-1]['tripped'] == 1 and statuses[-1]['emergency_stop'] == 1  # armed
    core.on_reject('traction_command', 'bad_crc', t)  # a corrupt record restarts the latch
    run(0.06, lambda: None)
    assert statuses[-1]['tripped'] == 1 and statuses[-1]['emergency_stop'] == 0
    run(0.1, lambda: command(0))
    run(0.1, lambda: command(DEMAND))
    assert statuses[-1]['tripped'] == 0 and statuses[-1]['trip_cause'] == 'none'
