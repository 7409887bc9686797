"""Traction core: the thesis sequences with a fixed clock, and every trip path."""

from __future__ import annotations

import pytest
from test_hardware_cuts import declared

from agv_nodes.traction.core import TractionCore, TractionParams

DT = 0.010


def cmd(demand: int = 0, manual: int = 0, speed: int = 0, reverse: int = 0,
        priority: int = 0) -> dict:
    return {'manual': manual, 'manual_speed': speed, 'reverse': reverse, 'demand': demand,
            'executive_priority': priority}


def link(speed: int = 0, reverse: int = 0, executive: int = 0) -> dict:
    return {'executive_priority': executive, 'reverse': reverse, 'speed': speed}


class Bench:
    """Drives a TractionCore with a fixed clock; the executive republishes its command."""

    def __init__(self, **params) -> None:
        params.setdefault('control', 'open_loop_1983')  # the listing, unless a test says not
        self.core = TractionCore(TractionParams(**params))
        self.t = 0.0
        self.command = cmd()
        self.link: dict | None = None
        self.log: list[tuple[float, dict]] = []
        self.sent = -1.0  # when the last command went

    def run(self, seconds: float, send: bool = True) -> None:
        end = self.t + seconds
        while self.t < end - 1e-9:
            if send and round(self.t / DT) % 5 == 0:  # commands every 50 ms
                self.core.on_record('traction_command', self.command, self.t)
                self.sent = self.t
                if self.link is not None:
                    self.core.on_record('traction_link', self.link, self.t)
            out = self.core.tick(self.t)
            self.log.append((self.t, out['traction_drive']))
            self.t = round(self.t + DT, 6)

    def arm(self) -> None:
        """Clear the start-up trip: e-stop, then a non-zero demand (the latch rule)."""
        self.command = cmd(0)
        self.run(0.1)
        self.command = cmd(1)
        self.run(0.02)

    def duties(self, since: float = 0.0) -> list[tuple[float, int, int]]:
        """(time, signed duty, field_forward) at each change of the drive record."""
        out, last = [], None
        for t, d in self.log:
            if t < since:
                continue
            signed = d['armature_duty'] if d['field_forward'] else -d['armature_duty']
            key = (signed, d['field_forward'], d['field_enable'])
            if key != last:
                out.append((round(t, 3), signed, d['field_enable']))
                last = key
        return out


def test_starts_tripped_and_needs_estop_then_nonzero():
    b = Bench()
    b.command = cmd(30)
    b.run(0.5)  # a drive demand alone does not clear the start-up trip
    assert b.core.tripped and b.core.trip_cause == 'startup'
    assert b.log[-1][1]['contactor'] == 0 and b.log[-1][1]['armature_duty'] == 0
    b.command = cmd(0)
    b.run(0.1)
    assert b.core.tripped
    b.command = cmd(30)
    b.run(0.1)
    assert not b.core.tripped and b.log[-1][1]['contactor'] == 1


def test_slew_from_rest_to_50_percent_follows_the_listing():
    """16 -> (flip) -> 16 -> 32 -> 48 -> 50, with the prose's 100/200 ms waits."""
    b = Bench()
    b.arm()
    t0 = b.t
    b.command = cmd(50)
    b.run(2.0)
    steps = [(round(t - t0, 2), duty) for t, duty, _f in b.duties(t0) if duty]
    duties = [d for _t, d in steps]
    assert duties == [16, 32, 48, 50]
    times = [t for t, _d in steps]
    # FLIP (INIT left the field reversed): 100 ms off + 100 ms build-up before the first 16 %,
    # then a 200 ms runout after each limited step (the FLIP pass's own 16 % counts once),
    # each wait ending on the first pass after it
    runout = declared('traction', 'TractionParams')['runout_wait']
    gaps = [later - earlier for earlier, later in zip(times, times[1:], strict=False)]
    assert 2 * runout - 1e-9 <= gaps[0] <= 2 * runout + DT + 1e-9  # + a repeated 16 step
    assert all(runout - 1e-9 <= gap <= runout + DT + 1e-9 for gap in gaps[1:]), gaps


def test_listing_delays_option_halves_the_waits():
    slow, fast = Bench(), Bench(runout_wait=0.100, field_wait=0.050)
    for b in (slow, fast):
        b.arm()
        b.command = cmd(50)
        b.run(2.0)
    t_slow = next(t for t, d, _f in slow.duties() if d == 50)
    t_fast = next(t for t, d, _f in fast.duties() if d == 50)
    assert t_fast < t_slow - 0.3


def test_reversal_disables_flips_the_field_and_re_enables():
    b = Bench()
    b.arm()
    b.command = cmd(20)
    b.run(2.0)
    assert b.core.dcycle == 20 and b.core.field_forward
    t0 = b.t
    b.command = cmd(-20)
    b.run(2.0)
    seq = b.duties(t0)
    signed = [d for _t, d, _f in seq]
    # 20 -> 4 (limited step) -> field off (flip) -> -12 -> -16 -> -20 in reverse
    assert signed[:3] == [20, 4, 0]
    assert seq[2][2] == 0  # field disabled during the flip
    assert [d for d in signed if d < 0] == [-12, -16, -20]
    off = next(t for t, d, f in seq if f == 0)
    on = next(t for t, d, f in seq if d == -12)
    # 100 ms decay + 100 ms build-up, the next pass after them
    wait = declared('traction', 'TractionParams')['field_wait']
    assert 2 * wait - 1e-9 <= on - off <= 2 * wait + DT + 1e-9, on - off


def test_emergency_stop_is_minus_5_percent_plug_braking():
    b = Bench()
    b.arm()
    b.command = cmd(20)
    b.run(2.0)
    b.command = cmd(0)
    b.run(2.0)
    assert b.core.ref == -5 and b.core.estop
    last = b.log[-1][1]
    assert last['field_forward'] == 0 and last['armature_duty'] == 5  # reverse field, 5 %
    assert b.core.status()['emergency_stop'] == 1
    assert b.core.status()['source'] == 'emergency_stop'


@pytest.mark.parametrize('mode, armature_off_within', [('immediate', 0.061),  # 1 command
                                                       ('as_listed', 0.5)])
def test_emergency_stop_cuts_the_armature_at_once_unless_as_listed(mode, armature_off_within):
    b = Bench(emergency_stop=mode)
    b.arm()
    b.command = cmd(55)
    b.run(3.0)
    assert b.log[-1][1]['armature_duty'] == 55
    t0 = b.t
    b.command = cmd(0)
    b.run(1.5)
    forward = [t for t, d in b.log if t >= t0 and d['field_forward'] and
               d['armature_enable'] and d['armature_duty'] > 0]
    pushing_for = (max(forward) - t0 + DT) if forward else 0.0
    if mode == 'immediate':
        assert pushing_for <= armature_off_within
    else:  # 55 -> 39 -> 23 -> 7 with a 200 ms runout after each limited step
        assert pushing_for >= armature_off_within
    last = b.log[-1][1]
    assert last['field_forward'] == 0 and last['armature_duty'] == 5  # then plug braking


@pytest.mark.parametrize('control', ['open_loop_1983', 'closed_loop'])
def test_immediate_emergency_stop_acts_on_the_record_not_the_next_pass(control):
    b = Bench(control=control)
    b.arm()
    b.command = cmd(55)
    b.run(3.0)
    assert b.log[-1][1]['armature_duty'] > 0
    out = b.core.on_record('traction_command', cmd(0), b.t)  # between two loop passes
    assert out['traction_drive']['armature_enable'] == 0
    assert out['traction_drive']['armature_duty'] == 0 and out['traction_drive']['contactor']
    as_listed = Bench(control=control, emergency_stop='as_listed')
    as_listed.arm()
    as_listed.command = cmd(55)
    as_listed.run(3.0)
    assert as_listed.core.on_record('traction_command', cmd(0), as_listed.t) is None


@pytest.mark.parametrize('reaction', ['at_once', 'loop'])
def test_a_new_link_is_acted_on_at_once_in_the_closed_loop(reaction):
    b = Bench(control='closed_loop', link_reaction=reaction)
    b.arm()
    b.command = cmd(60)
    b.link = link(speed=40)  # Position priority, forward 40 %
    b.run(4.0)
    cruising = b.log[-1][1]['armature_duty']
    assert cruising > 0 and b.core.source == 'position'
    t = b.t - DT / 2  # between two loop passes
    passes = b.core.watchdog
    # the same contents again (navigation's 20 ms repeat) change nothing: no extra pass
    assert b.core.on_record('traction_link', link(speed=40), t) is None
    out = b.core.on_record('traction_link', {**link(speed=40), 'stop_in': 5}, t)
    if reaction == 'loop':
        assert out is None  # the listing: the next pass of START reads it
        return
    # a controlled stop 5 mm ahead at 0.5 m/s: the drive is cut in this very record
    assert out['traction_drive']['armature_enable'] == 0
    assert out['traction_drive']['armature_duty'] == 0 and out['traction_drive']['contactor']
    assert b.core.watchdog == (passes + 1) & 0xFF  # that record's own pass


def test_the_open_loop_keeps_the_listings_passes_for_a_new_link():
    b = Bench(control='open_loop_1983', link_reaction='at_once')
    b.arm()
    b.command = cmd(60)
    b.link = link(speed=40)
    b.run(4.0)
    assert b.core.on_record('traction_link', link(speed=0), b.t - DT / 2) is None


def test_manual_bypasses_emergency_and_radio_stop():
    b = Bench()
    b.arm()
    b.core.on_radio_stop(True, b.t)
    b.command = cmd(0, manual=1, speed=9)  # byte 1 = 0001 0011 = 19 -> REF 19 %
    b.run(2.0)
    assert b.core.ref == 19 and b.core.source == 'manual'
    assert b.core.dcycle == 19 and b.log[-1][1]['armature_enable'] == 1
    b.command = cmd(0, manual=1, speed=9, reverse=1)  # 1001 0011 = -109 -> clamped -80
    b.run(0.05)
    assert b.core.ref == -109


def test_radio_stop_checked_after_estop_before_source():
    b = Bench()
    b.arm()
    b.command = cmd(30)
    b.run(2.0)
    b.core.on_radio_stop(True, b.t)
    b.run(0.1)
    assert b.log[-1][1]['armature_enable'] == 0 and b.core.dcycle == 0
    assert b.core.status()['radio_stop'] == 1 and b.core.source == 'radio_stop'
    b.command = cmd(0)  # e-stop comes first in GETREF: it is served despite the radio stop
    b.run(0.5)
    assert b.core.source == 'emergency_stop'
    b.core.on_radio_stop(False, b.t)
    b.command = cmd(30)
    b.run(2.0)
    assert b.core.dcycle == 30


def test_source_switching_between_executive_and_link():
    b = Bench()
    b.arm()
    b.command = cmd(60)
    b.link = link(executive=1)  # 40H: speed control with the executive
    b.run(2.0)
    assert b.core.ref == 60 and b.core.source == 'executive'
    b.link = link(speed=20)  # 14H: Position priority, forward, 20 %
    b.run(2.0)
    assert b.core.ref == 20 and b.core.source == 'position' and b.core.dcycle == 20
    b.link = link(speed=0)  # 00H at the centre view: REF 0, armature off, coast
    b.run(1.0)
    assert b.core.ref == 0 and b.log[-1][1]['armature_enable'] == 0
    b.link = link(speed=20, reverse=1)  # 34H: bit 5 set -> NEG -> -20 (overshoot reverse creep)
    b.run(0.05)
    assert b.core.ref == -20
    b.command = cmd(60, priority=1)  # executive holds priority (via_executive)
    b.run(0.6)  # the pass in progress finishes its waits (FLIP) before GETREF runs again
    assert b.core.ref == 60


def test_8bit_overflow_option():
    sat, wrap = Bench(), Bench(arithmetic='faithful_8bit')
    for b in (sat, wrap):
        b.core.ref, b.core.speed = 50, -80
        b.core._sum()
    assert sat.core.error == 16
    assert wrap.core.error == -16  # 130 wraps to -126: the listing drives the wrong way


# -- trips -------------------------------------------------------------------------------------
def running() -> Bench:
    b = Bench()
    b.arm()
    b.command = cmd(40)
    b.run(2.0)
    assert not b.core.tripped and b.log[-1][1]['armature_enable'] == 1
    return b


def assert_tripped(b: Bench, cause: str) -> None:
    assert b.core.tripped and b.core.trip_cause == cause
    drive = b.log[-1][1]
    assert drive['contactor'] == 0 and drive['armature_enable'] == 0
    assert drive['field_enable'] == 0 and drive['armature_duty'] == 0
    status = b.core.status()
    assert status['tripped'] == 1 and status['trip_cause'] == cause


def test_stale_command_trips_within_command_timeout(fault_table):
    """The contactor opens on the first pass after the command is command_timeout old."""
    b = running()
    t0, last = b.t, b.sent
    b.run(0.5, send=False)
    trip_t = next(t for t, d in b.log if t >= t0 and d['contactor'] == 0)
    timeout = declared('traction', 'TractionParams')['command_timeout']
    # both on the loop's 10 ms grid: the age that trips is the timeout or one pass more
    assert timeout - 1e-9 <= trip_t - last <= timeout + DT + 1e-9, trip_t - last
    assert_tripped(b, 'stale_command')
    fault_table.add('traction: executive command stops (lock step)', 'contactor open, trip '
                    'latched: stale_command', f'contactor open {trip_t - last:.2f} s after the '
                    'last command')


def test_stale_confirm_waits_for_odometry_so_a_clock_jump_alone_does_not_trip():
    core = TractionCore(TractionParams(stale_confirm=5, command_timeout=0.15))
    odo = {'left_speed': 500, 'right_speed': 500, 'left_distance': 0, 'right_distance': 0,
           'sample': 0}
    t = 0.0
    for k in range(200):  # armed and running, odometry at 100 Hz
        t = k * 0.01
        core.on_record('wheel_odometry', odo, t)
        if k % 5 == 0:
            core.on_record('traction_command', cmd(0 if k < 10 else 40), t)
        core.tick(t)
    assert not core.tripped
    core.tick(t + 0.17)  # starved: the clock jumped 170 ms, the queued records not yet taken
    assert not core.tripped
    for k in range(5):  # odometry arrives, the command does not: the executive is silent
        core.on_record('wheel_odometry', odo, t + 0.17 + k * 0.01)
    core.tick(t + 0.21)
    assert core.tripped and core.trip_cause == 'stale_command'


def test_stalled_loop_trips(fault_table):
    b = running()
    b.core.on_record('traction_command', b.command, b.t + 0.3)
    b.t += 0.3  # the process was stopped for 300 ms; the next pass notices the gap
    b.run(0.02)
    assert_tripped(b, 'stalled_loop')
    fault_table.add('traction: its own loop stalls 300 ms (lock step)', 'trip: stalled_loop',
                    'tripped on the next pass')


@pytest.mark.parametrize('reason, trips', [('bad_crc', True), ('spare_set', True),
                                           ('wrong_length', True), ('bad_value', True),
                                           ('repeated_counter', False)])
def test_corrupt_record_trips(reason, trips, fault_table):
    b = running()
    b.core.on_reject('traction_command', reason, b.t)
    b.run(0.02)
    if trips:
        assert_tripped(b, 'corrupt_record')
    else:
        assert not b.core.tripped
    fault_table.add(f'traction: command rejected for {reason} (lock step)',
                    'trip: corrupt_record' if trips else 'ignored (not new data), no trip',
                    'tripped' if trips else 'running on')


def test_stale_link_trips_only_when_position_has_priority(fault_table):
    b = running()
    b.link = link(executive=1)
    b.run(0.5)
    b.link = None  # navigation falls silent while the executive has priority: no trip
    b.run(0.5)
    assert not b.core.tripped
    b.link = link(speed=20)  # Position takes priority ...
    b.run(0.5)
    b.link = None  # ... and falls silent
    b.run(0.5)
    assert_tripped(b, 'stale_link')
    fault_table.add('traction: navigation link stops while Position has priority (lock step)',
                    'trip: stale_link (no trip while the executive has priority)', 'as expected')


def test_trip_latches_until_estop_then_nonzero():
    b = running()
    b.core.on_reject('traction_link', 'bad_crc', b.t)
    b.run(1.0)  # the same non-zero command keeps arriving: still latched
    assert_tripped(b, 'corrupt_record')
    b.command = cmd(0)
    b.run(0.2)
    assert b.core.tripped
    b.command = cmd(40)
    b.run(2.0)
    assert not b.core.tripped and b.core.dcycle == 40
