"""Route following settings: every parameter of the node, its default and its meaning.

The nested groups give dotted names: `wire.kp`, `image.min_run`, `steering.law`,
`turning.approach_speed`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from agv_nodes.settings import setting


@dataclass
class WireParams:
    """Guide-wire steering (Baker 1983, 3.5.3, 6.2.1, 7.2; tuned in bench/route_bench.py)."""

    coil_spacing: float = setting(0.20, 'm between the two pickup coils (as fitted on the '
                                  'truck)', lo=0.02, hi=1.0)
    coil_height: float = setting(0.08, 'm of the coils above the floor', lo=0.01, hi=0.5)
    nominal: float = setting(732.0, 'coil reading over the wire, counts (calibration: either '
                             'coil with the wire midway between them)', lo=10.0, hi=4095.0)
    kp: float = setting(20.0, 'rad of steering per m of lateral offset', lo=0.0, hi=200.0)
    ki: float = setting(20.0, 'rad of steering per m s of integrated offset', lo=0.0, hi=200.0)
    kd: float = setting(2.0, 'rad of steering per m/s of offset rate', lo=0.0, hi=50.0)
    max_steer: float = setting(math.radians(40.0), 'largest steering angle asked for, rad',
                               lo=0.05, hi=1.5)
    lost_level: float = setting(0.25, 'fraction of nominal below which the wire is not there',
                                lo=0.01, hi=1.0)
    lost_samples: int = setting(5, 'consecutive weak guide_wire samples (100 Hz) before LOST',
                                lo=1, hi=100)
    found_level: float = setting(0.55, 'fraction of nominal at which an SRM has found a wire',
                                 lo=0.01, hi=2.0)
    srm_timeout: float = setting(12.0, 'seconds an SRM may search for a wire before it ends '
                                 'LOST', lo=1.0, hi=120.0)
    found_hold: float = setting(0.5, 'seconds the wire_found state is shown after an SRM',
                                lo=0.0, hi=10.0)
    wheelbase: float = setting(1.20, 'm between the axles (the SRM turns the truck by v '
                               'tan(delta) / wheelbase)', lo=0.1, hi=5.0)
    steer_rate: float = setting(math.radians(45.0), 'rad/s of the steering actuator (the SRM '
                                'models where it is)', lo=0.01, hi=10.0)
    look_ahead: float = setting(0.40, 'capture: m ahead on the wire at which the front wheels '
                                'aim', lo=0.05, hi=5.0)
    capture_done: float = setting(0.03, 'capture: m of offset, held for 0.3 s, that ends it',
                                  lo=0.001, hi=0.5)


@dataclass
class ImageParams:
    """Camera window calibration and noise filter (Rajagopalan 1991, 4.2, Table 6.1, App. F.2)."""

    depth: float = setting(0.050, 'm of the camera window along travel (64 rows)', lo=0.01,
                           hi=0.5)
    width: float = setting(0.250, 'm of the camera window across (128 columns)', lo=0.05,
                           hi=1.0)
    min_run: int = setting(16, 'noise filter: shortest dark run taken as track, px (thesis: 2 '
                           'bytes = 16)', lo=1, hi=64)
    rows: tuple[int, ...] = setting((), 'rows analysed, 0-63 (empty: all 64; the thesis used '
                                    '3, 29, 55)', lo=0, hi=63)
    normal_width: float = setting(0.0, 'px of a normal track (0: learnt from the first frames)',
                                  lo=0.0, hi=128.0)
    wide_factor: float = setting(1.35, 'a run this many times wider than normal flags a road '
                                 'sign', lo=1.0, hi=5.0)
    sign_rows: int = setting(10, 'rows with an edge column dark that flag a branch (thesis '
                             '4.3)', lo=1, hi=64)
    saturated_fraction: float = setting(0.7, 'dark pixels beyond this fraction make a '
                                        'saturated frame (ignored)', lo=0.1, hi=1.0)


@dataclass
class SteeringParams:
    """Camera steering laws and the CONCIC-II geometry (Rajagopalan 1991, 5.2; Table 6.1)."""

    law: str = setting('pi', 'camera steering law: p (thesis Eq 5.4) or pi (Eq 5.6)',
                       choices=('p', 'pi'))
    gain_d: float = setting(2.5, 'rad of caster angle per m of eps_d (thesis P = 2.5)', lo=0.0,
                            hi=100.0)
    gain_theta: float = setting(0.0, 'rad per rad of eps_theta (not fed back in the thesis '
                                'experiments)', lo=0.0, hi=10.0)
    gain_i: float = setting(0.07, 'integral gain (thesis I = 0.07; see integral_form)', lo=0.0,
                            hi=100.0)
    # Eq 5.8 as printed adds G3 eps_d(n) every frame, without the Delta-T of Eq 5.6: at ~20
    # frames/s that is 1.4 rad per m s (Rajagopalan 1991, 5.2.3). The default follows the
    # printed velocity form the vehicle ran.
    integral_form: str = setting('per_frame', 'integral term: per frame as Eq 5.8 is printed, '
                                 'or x Delta-T as in Eq 5.6 (with_dt)',
                                 choices=('per_frame', 'with_dt'))
    max_angle: float = setting(math.radians(60.0), 'caster angle limit, rad', lo=0.05, hi=1.5)
    # With G_theta 0.4 the schedule kept the 0.065 m step's overshoot under 5 % up to 0.79 m/s
    # (bench/route_bench.py step).
    schedule_speed: float = setting(0.0, 'above this cruise the eps_d gain falls as 1/speed, '
                                    "so the loop's bandwidth in distance stays that of this "
                                    'speed, m/s (0: off, the thesis)', lo=0.0, hi=2.0)
    # A step's transient then does not wind the integral up; a curve's small steady offset
    # still does.
    integral_band: float = setting(0.0, 'the integral gathers only while |eps_d| is within '
                                   'this, m (0: always, the thesis)', lo=0.0, hi=0.2)
    wheel_span: float = setting(0.52, 'm between the drive wheels, L', lo=0.1, hi=2.0)
    caster_distance: float = setting(0.31, 'm from the axle to the caster, L_a', lo=0.05,
                                     hi=2.0)
    caster_trail: float = setting(0.05, 'm of caster trail, s', lo=0.0, hi=0.5)
    absent_frames: int = setting(4, 'consecutive frames without track before the motor-off '
                                 'stop', lo=1, hi=100)
    # At 0 the drive's trapezoid ramps both wheels alike, without steering, until the slower
    # one is at cruise: from 40 deg the window loses the tape before then (bench/route_bench.py).
    set_off_acceleration: float = setting(0.2, 'speed ramp asked for when setting off from '
                                          'rest, m/s^2 (0: cruise at once)', lo=0.0, hi=2.0)


@dataclass
class TurningParams:
    """Taking a branch at a road sign (Rajagopalan 1991, App. F.6).

    The manoeuvre itself is not described there: a spin in place, which the differential drive
    allows, is assumed.
    """

    camera_ahead: float = setting(0.64, 'm, L_c: camera window centre ahead of the axle '
                                  'centre', lo=0.0, hi=2.0)
    # The thesis drives L_c from the detection, which puts the axle where the window was when
    # a frame first showed the branch: up to one frame's travel (31 mm at 0.63 m/s) and the
    # ten rows the edge column needs short of the crossing.
    crossing_from: str = setting('image', 'where the axle stops to turn: at the crossing '
                                 "placed from the branch's near edge in each frame that shows "
                                 "it, plus half the tape's width (image), or L_c + detect_lead "
                                 'past the sighting (thesis, App. F.6)',
                                 choices=('image', 'thesis'))
    detect_lead: float = setting(0.045, 'm added to L_c under crossing_from thesis (the rows '
                                 'needed to flag the branch)', lo=0.0, hi=0.5)
    approach_speed: float = setting(0.16, 'm/s once the chosen branch is in sight (thesis: '
                                    '"decelerate gradually")', lo=0.02, hi=1.0)
    position_tolerance: float = setting(0.004, 'm: the axle centre counts as over the '
                                        'crossing', lo=0.0005, hi=0.1)
    stop_deceleration: float = setting(0.25, "m/s^2 of the stops (the drive's trapezoid: "
                                       '0.3)', lo=0.01, hi=2.0)
    spin_speed: float = setting(0.15, 'wheel speed of the spin onto a branch, m/s (each wheel, '
                                'opposite ways)', lo=0.02, hi=0.5)
    spin_angle: float = setting(90.0, 'degrees of the spin (the branches of the floor are at '
                                'right angles)', lo=1.0, hi=180.0)
    angle_tolerance: float = setting(0.2, 'degrees of the spin, by wheel odometry, that count '
                                     'as done', lo=0.01, hi=10.0)
    turn_timeout: float = setting(20.0, 'seconds from the sighting to following the branch '
                                  'before the motors are cut and LOST reported (bench: 6-10 '
                                  's)', lo=1.0, hi=300.0)


@dataclass
class RouteParams:
    """All route-following settings."""

    period: float = setting(0.010, 'seconds per pass of the steering loop (and per '
                            'steering_command record)', lo=0.001, hi=0.1)
    status_period: float = setting(0.050, 'seconds between route_status records', lo=0.01,
                                   hi=1.0)
    vehicle: str = setting('electruk', 'steering output: Ackermann angle (electruk) or '
                           'differential wheel speeds (concic2)', choices=('electruk', 'concic2'))
    camera_speed: float = setting(0.47, 'cruise speed in camera mode, m/s (thesis: "normal '
                                  'industrial speed")', lo=0.0, hi=1.2)
    wire: WireParams = field(default_factory=WireParams)
    image: ImageParams = field(default_factory=ImageParams)
    steering: SteeringParams = field(default_factory=SteeringParams)
    turning: TurningParams = field(default_factory=TurningParams)
