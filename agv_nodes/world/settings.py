"""World settings: every parameter of the world node, its default and its meaning.

WorldParams is the simulated hardware (WorldCore); its nested groups give dotted names
(`electruk.payload`, `sensor.ambient`, `pickup.noise`, ...). WorldNodeSettings is what the
world node has besides: the layout, its clock, and how it waits for and paces the graph.
Values marked [A] are assumptions, [T] the thesis's, [D] derived from the thesis's figures
and tables (docs/references.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

from agv_nodes.markers import ELEMENT_HEIGHT, ELEMENT_WIDTH, THRESHOLDS
from agv_nodes.settings import ProcessSettings, setting


@dataclass
class ElectrukParams:
    """The A.W.D. Electruk tug (Baker 1983).

    [A] unless noted: chosen so that 80 % duty gives about 1 m/s unloaded, 20 % about 0.2 m/s
    and nothing moves below about 5 %.
    """

    wheelbase: float = setting(1.20, 'm between the axles', lo=0.1, hi=5.0)
    track: float = setting(0.80, 'm between the rear wheels', lo=0.1, hi=3.0)
    wheel_radius: float = setting(0.20, 'm, the driven rear wheels', lo=0.02, hi=1.0)
    mass: float = setting(800.0, 'kg, the truck with its batteries', lo=10.0, hi=10000.0)
    payload: float = setting(0.0, 'kg on the truck (thesis: up to 1000)', lo=0.0, hi=2000.0)
    inertia_factor: float = setting(1.08, 'rotating masses as extra equivalent mass (x the '
                                    'mass)', lo=1.0, hi=3.0)
    battery_voltage: float = setting(24.0, 'V of the battery [T 6.1]', lo=1.0, hi=200.0)
    motors: int = setting(2, 'drive motors, in parallel [T 6.1]', lo=1, hi=8)
    armature_resistance: float = setting(0.12, 'ohm per motor', lo=0.001, hi=10.0)
    armature_inductance: float = setting(0.0012, 'H per motor', lo=1e-5, hi=1.0)
    k_phi: float = setting(0.0562, 'V s/rad (= N m/A) per motor at full field', lo=0.001,
                           hi=10.0)
    field_time_constant: float = setting(0.060, 's of the field build-up (the 100 ms waits of '
                                         'FLIP cover ~1.7 time constants)', lo=0.001, hi=5.0)
    gear_ratio: float = setting(63.0, 'motor revolutions per wheel revolution (gearbox and '
                                'chain)', lo=1.0, hi=1000.0)
    drivetrain_friction: float = setting(0.50, 'N m per motor at the motor shaft (Coulomb)',
                                         lo=0.0, hi=50.0)
    viscous_friction: float = setting(0.0004, 'N m s/rad per motor', lo=0.0, hi=1.0)
    rolling_resistance: float = setting(0.015, 'fraction of the weight on the wheels', lo=0.0,
                                        hi=0.5)
    current_limit: float = setting(60.0, 'A per motor, the controller limit (it bounds plug '
                                   'braking)', lo=1.0, hi=1000.0)
    max_steer: float = setting(math.radians(40.0), 'largest front wheel angle, rad', lo=0.05,
                               hi=1.5)
    steer_rate: float = setting(math.radians(45.0), 'rad/s slew of the steering actuator',
                                lo=0.01, hi=10.0)


@dataclass
class Concic2Params:
    """CONCIC-II (Rajagopalan 1991, 6.3.1-6.3.2, Table 6.1, App. B.3-B.5, App. C)."""

    wheel_radius: float = setting(0.075, 'm [T Table B.3]', lo=0.01, hi=0.5)
    wheel_span: float = setting(0.52, 'm between the drive wheels, L [D]', lo=0.1, hi=2.0)
    caster_distance: float = setting(0.31, 'm from the axle to the caster, L_a [D]', lo=0.05,
                                     hi=2.0)
    caster_trail: float = setting(0.05, 'm of caster trail, s [D]', lo=0.0, hi=0.5)
    camera_distance: float = setting(0.64, 'm from the axle centre to the camera window '
                                     'centre, L_c [D]', lo=0.0, hi=2.0)
    acceleration: float = setting(0.30, "m/s^2 of the LM628 trapezoid (both wheels' shared "
                                  'rate, fixed during motion)', lo=0.01, hi=5.0)
    lag: float = setting(0.05, 's, time constant of the wheel speed loops', lo=0.001, hi=1.0)
    # 5 mm from 0.16 m/s (Rajagopalan 1991, 7.3.4).
    coast_deceleration: float = setting(2.6, 'm/s^2 of a motor-off coast', lo=0.1, hi=20.0)
    max_wheel_speed: float = setting(1.14, 'm/s of a wheel (145 rpm)', lo=0.1, hi=5.0)


@dataclass
class SensorParams:
    """Optics and electronics of the Mk 1 marker sensor ([A] unless noted)."""

    focus: float = setting(0.300, 'm from the lens to the marker plane in focus [T 5.1]',
                           lo=0.1, hi=1.0)
    aperture_width: float = setting(0.014, "m at focus: the photodiode's image inside its 20 mm "
                                    'cell', lo=0.001, hi=0.05)
    aperture_height: float = setting(ELEMENT_HEIGHT, 'm at focus [T 5.1]', lo=0.001, hi=0.1)
    flat_height: float = setting(0.5, 'fraction of the aperture height at full sensitivity',
                                 lo=0.0, hi=1.0)
    base_blur: float = setting(0.0015, 'm, blur sigma in focus (lens, photodiode edge)',
                               lo=0.0, hi=0.05)
    defocus_blur: float = setting(0.15, 'blur sigma per metre of range error', lo=0.0, hi=2.0)
    dark_level: float = setting(8.0, 'ADC counts of the front end with the IREDs off', lo=0.0,
                                hi=255.0)
    # A fault test blinds the sensor while the world runs.
    ambient: float = setting(0.0, 'ambient IR light, ADC counts, lit and dark alike (255 '
                             'saturates: a blinded sensor)', lo=0.0, hi=400.0, read_only=False)
    ambient_noise: float = setting(0.5, 'counts rms of ambient flicker (common to lit and '
                                   'dark)', lo=0.0, hi=20.0)
    noise: float = setting(1.0, 'ADC noise, counts rms of each conversion', lo=0.0, hi=20.0)
    unit: str = setting('sensor1', 'Table 7.1 sensor whose gains the photodiode model '
                        'reproduces', choices=tuple(THRESHOLDS))
    gains: tuple[float, ...] = setting((), 'per detector: counts for white paper filling the '
                                       'patch at focus (empty: derived from Table 7.1)',
                                       lo=0.0, hi=100000.0, length=8)
    blacks: tuple[float, ...] = setting((), 'per detector: the black level as a fraction of '
                                        'white, card and stray light (empty: derived from '
                                        'Table 7.1)', lo=0.0, hi=1.0, length=8)
    skew: tuple[float, ...] = setting((0.0,) * 8, 'm, along-track misalignment of each '
                                      'detector', lo=-0.02, hi=0.02, length=8)
    column_pitch: float = setting(ELEMENT_WIDTH, 'm at focus between adjacent columns',
                                  lo=0.005, hi=0.1)
    row_pitch: float = setting(ELEMENT_HEIGHT, 'm at focus between the two rows', lo=0.005,
                               hi=0.2)


@dataclass
class PickupParams:
    """Guide-wire coil geometry and scaling ([A])."""

    coil_spacing: float = setting(0.20, 'm between the two coils (each half of it off '
                                  'centre)', lo=0.02, hi=1.0)
    coil_height: float = setting(0.08, 'm of the coils above the wire', lo=0.01, hi=0.5)
    gain: float = setting(75.0, 'ADC counts per unit of 2h/(h^2 + y^2), 1/m (12-bit full '
                          'scale: 4095)', lo=1.0, hi=10000.0)
    noise: float = setting(2.0, 'counts rms of each coil', lo=0.0, hi=100.0)
    reach: float = setting(1.5, 'm: wire segments farther than this are ignored', lo=0.1,
                           hi=10.0)

    @property
    def nominal(self) -> float:
        """Counts of each coil with the sensor point right over a long straight wire."""
        h, y = self.coil_height, self.coil_spacing / 2.0
        return self.gain * 2.0 * h / (h * h + y * y)


@dataclass
class CameraParams:
    """Binary camera window and noise ([T] Table 6.1, Rajagopalan 1991, Table 6.3)."""

    depth: float = setting(0.050, 'm of the window along travel (64 rows)', lo=0.01, hi=0.5)
    width: float = setting(0.250, 'm of the window across (128 columns)', lo=0.05, hi=1.0)
    specks: int = setting(6, 'random dark runs per frame (dirt, pixel differences)', lo=0,
                          hi=100)
    speck_max: int = setting(6, 'px of the longest speck (below the 16 px noise filter)', lo=1,
                             hi=64)


@dataclass
class WorldParams:
    """The simulated hardware: rates, the trip relay, conveyors, and each device's model."""

    seed: int = setting(1, 'random seed of all noise', lo=0, hi=2**31 - 1)
    sample_rate: float = setting(340.0, 'marker sensor snapshots per second, the world step '
                                 '(thesis 5.3.5.2: 340 Hz)', lo=50.0, hi=2000.0)
    substeps: int = setting(4, 'physics steps per sample', lo=1, hi=100)
    guide_wire_rate: float = setting(100.0, 'guide_wire records per second', lo=1.0,
                                     hi=1000.0)
    odometry_rate: float = setting(100.0, 'wheel_odometry records per second', lo=1.0,
                                   hi=1000.0)
    conveyor_rate: float = setting(20.0, 'conveyor_status records per second', lo=1.0,
                                   hi=1000.0)
    camera_rate: float = setting(20.0, 'binary camera frames per second [T Table 6.1: 20-25]',
                                 lo=1.0, hi=50.0)
    rear_camera: bool = setting(False, 'render the rear camera too')
    drive_watchdog: float = setting(0.200, 'seconds the traction_drive watchdog count may '
                                    'stall before the trip relay opens [T B.2.1]', lo=0.01,
                                    hi=5.0)
    steering_timeout: float = setting(0.200, 'seconds without a steering_command before the '
                                      'tug holds its angle and the CONCIC-II turns its motors '
                                      'off', lo=0.01, hi=5.0)
    ride_height_per_tonne: float = setting(0.008, 'm the marker card appears higher per 1000 '
                                           'kg of payload [A]', lo=0.0, hi=0.1)
    align_tolerance: float = setting(0.060, 'm from the stop marker within which a conveyor '
                                     'transfer works', lo=0.001, hi=1.0)
    conveyor_speed: float = setting(0.25, 'm/s of the conveyors', lo=0.01, hi=2.0)
    transfer_length: float = setting(0.80, 'm a load travels between conveyors', lo=0.05,
                                     hi=5.0)
    start_loaded: tuple[str, ...] = setting((), 'truck conveyors carrying a load at start',
                                            choices=('first', 'second'))
    electruk: ElectrukParams = field(default_factory=ElectrukParams)
    concic2: Concic2Params = field(default_factory=Concic2Params)
    sensor: SensorParams = field(default_factory=SensorParams)
    pickup: PickupParams = field(default_factory=PickupParams)
    camera: CameraParams = field(default_factory=CameraParams)


@dataclass
class WorldNodeSettings(ProcessSettings):
    """The world node's own parameters (besides WorldParams).

    The layout, /clock, and how it waits for the graph and paces itself on it.
    """

    layout: str = setting('demo_1983', 'layout name (config/layouts) or file path')
    remove_markers: tuple[str, ...] = setting((), 'marker cards taken off their stands (fault '
                                              'tests: a missing stop marker), by name: L0-L3, '
                                              'W2.1, ...')
    time_factor: float = setting(1.0, 'simulated seconds per real second (0 = as fast as '
                                 'possible)', lo=0.0, hi=1000.0)
    publish_clock: bool = setting(True, 'publish /clock (the graph runs on sim time with '
                                  'use_sim_time:=true)')
    clock_every: int = setting(1, 'samples per /clock message (1 = every sample; keep the '
                               'clock faster than the fastest node timer)', lo=1, hi=100)
    wait_for_links: tuple[str, ...] = setting((), 'links that must have matched before the '
                                              "world moves: NODE:RECORD (NODE's reader has "
                                              "matched the record's writer) or NODE>RECORD:N "
                                              "(NODE's writer has matched N readers); "
                                              'agv-launch names every link of the graph')
    peer_timeout: float = setting(60.0, 'seconds to wait for peers', lo=0.0, hi=3600.0)
    duration: float = setting(0.0, 'stop after this many simulated seconds (0 = run until '
                              'shut down)', lo=0.0, hi=1e6)
    start_paused: bool = setting(False, 'wait for ~/resume before moving')
    pace_nodes: tuple[str, ...] = setting((), 'nodes whose sim/progress the world paces on: it '
                                          'waits for one that lags (agv-launch names every '
                                          'node of the graph)')
    max_lag: float = setting(0.05, 'simulated seconds a paced node may lag the world before '
                             'the world waits (0 = never wait)', lo=0.0, hi=10.0)
    lag_patience: float = setting(0.5, 'real seconds the world waits for a lagging node before '
                                  'it carries on without it', lo=0.0, hi=60.0)
    ready_file: str = setting('', 'a file the world writes when it starts moving (empty: '
                              'none)')
    # A fault test cuts the wire while the world runs.
    wire_powered: bool = setting(True, 'guide-wire generator on (false: the wire is cut)',
                                 read_only=False)
