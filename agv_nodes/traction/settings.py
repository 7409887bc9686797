"""Traction settings: every parameter of the traction node, its default and its meaning."""

from __future__ import annotations

from dataclasses import dataclass

from agv_nodes.settings import setting


@dataclass
class TractionParams:
    """The speed program (thesis App. B.2), its trips and the closed loop."""

    loop_period: float = setting(0.010, 'seconds per pass of START (and per traction_drive '
                                 'record)', lo=0.001, hi=0.1)
    status_period: float = setting(0.050, 'seconds between traction_status records', lo=0.01,
                                   hi=1.0)
    runout_wait: float = setting(0.200, 'wait after a limited +-16 % step, s (thesis prose: '
                                 "0.200; the listing's delay formula: 0.100)", lo=0.0, hi=1.0)
    field_wait: float = setting(0.100, 'each FLIP wait and the start-up field build-up, s '
                                '(prose: 0.100; listing formula: 0.050)', lo=0.0, hi=1.0)
    field_duty: int = setting(90, 'field PWM duty, % (thesis 6.3: 90; the listing loads 98)',
                              lo=1, hi=100)
    step_limit: int = setting(16, 'largest change of the duty per pass, % (SUM)', lo=1, hi=80)
    max_duty: int = setting(80, 'largest armature duty, % (COMP: CP 80)', lo=1, hi=100)
    estop_ref: int = setting(-5, 'duty the emergency stop asks for, % (0FBH: plug braking)',
                             lo=-80, hi=0)
    arithmetic: str = setting('saturating', "SUM's difference: saturating (the intent) or the "
                              "listing's 8-bit wrap", choices=('saturating', 'faithful_8bit'))
    # The listing reaches the -5 % e-stop through SUM's 16 %-per-pass slew, each step followed
    # by the 200 ms runout: from 55 % the drive pushes for ~0.6 s after the e-stop, beyond the
    # 200 ms the fault tests allow.
    emergency_stop: str = setting('immediate', 'on byte 2 = 00H: cut the armature at once, '
                                  'then plug-brake (immediate), or slew down 16 % per pass with '
                                  'the runout waits as the listing does (as_listed)',
                                  choices=('immediate', 'as_listed'))
    # A recognition then reaches the drive in one chain of messages instead of waiting up to a
    # loop period (bench/latency_bench.py --live). The open loop always keeps the listing's
    # passes: its SUM slews 16 % per pass, so an extra pass would steepen its ramp.
    link_reaction: str = setting('at_once', 'a traction_link with new contents: run a '
                                 'closed-loop pass at once (at_once), or wait for the next loop '
                                 'pass as the listing does (loop)', choices=('at_once', 'loop'))
    # 150 ms = three 50 ms heartbeats: with the loop's 10 ms and the armature cut at once, the
    # drive is off within the 200 ms the fault tests allow after the executive goes silent.
    command_timeout: float = setting(0.150, "trip when the executive's command is older than "
                                     'this, s', lo=0.02, hi=5.0)
    link_timeout: float = setting(0.150, 'trip when the Position link being obeyed is older '
                                  'than this, s', lo=0.02, hi=5.0)
    # On sim time a node that was starved of CPU sees its clock jump ahead at once while the
    # record it waits for is still queued: counting odometry records that arrived since tells
    # a late record from a silent writer. On hardware the clock never jumps.
    stale_confirm: int = setting(0, 'wheel_odometry records (100 Hz) that must arrive after a '
                                 'command or link before its age alone trips (0: the timeout '
                                 'alone, as on the hardware)', lo=0, hi=1000)
    stall_limit: float = setting(0.200, 'trip when two loop passes are further apart than '
                                 'this, s', lo=0.02, hi=5.0)
    # The controlled stop of navigation (thesis 8.5) needs the closed loop, and it holds the
    # asked speed under load (bench/results/traction_bench.md).
    control: str = setting('closed_loop', 'speed control: a PI loop on wheel odometry '
                           "(closed_loop) or the listing's open loop (open_loop_1983)",
                           choices=('closed_loop', 'open_loop_1983'))
    kp: float = setting(40.0, 'closed loop: % duty per m/s of speed error', lo=0.0, hi=1000.0)
    ki: float = setting(60.0, 'closed loop: % duty per m of integrated speed error', lo=0.0,
                        hi=1000.0)
    max_accel: float = setting(0.5, 'closed loop: m/s^2 of the speed demand ramp, speeding up',
                               lo=0.01, hi=5.0)
    max_decel: float = setting(1.0, 'closed loop: m/s^2 of the ramp slowing down (plug braking '
                               'helps friction)', lo=0.01, hi=5.0)
    max_jerk: float = setting(2.0, 'closed loop: m/s^3 of the ramp', lo=0.01, hi=50.0)
    v_per_percent: float = setting(1.0 / 75.0, 'closed loop: m/s per % of demand above the '
                                   "dead band (the open loop's measured map)", lo=0.001, hi=0.1)
    dead_band: float = setting(5.0, 'closed loop: % of demand that moves nothing', lo=0.0,
                               hi=20.0)
    flip_hysteresis: float = setting(8.0, 'closed loop: smaller duties against the field '
                                     'coast instead of flipping it, %', lo=0.0, hi=80.0)
    brake_margin: float = setting(0.08, 'closed loop: m/s over the demand before plug braking '
                                  'starts', lo=0.0, hi=1.0)
    brake_gain: float = setting(60.0, 'closed loop: % reverse duty per m/s of overspeed',
                                lo=0.0, hi=1000.0)
    stop_decel: float = setting(0.30, 'controlled stop: m/s^2 of the profile v = sqrt(2 a d)',
                                lo=0.01, hi=5.0)
    coast_decel: float = setting(0.50, 'controlled stop: m/s^2 the truck loses coasting; the '
                                 'drive is cut this far out', lo=0.01, hi=5.0)
