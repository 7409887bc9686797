"""The runs of bench/concic2_thesis_bench.py: the CONCIC-II on a tape floor, in lock step.

The world core (camera windows rendered at the camera rate, noise, the vehicle model) with the
route-following core in camera mode (route_command mode 'camera'), seeded; the experiments of
Rajagopalan 1991, 7.3 as functions of the vehicle model and the steering settings, and the
drive's open-loop figures.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

from agv_nodes.harness import Harness
from agv_nodes.package_share import config_dir
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import ImageParams, RouteParams, SteeringParams
from agv_nodes.settings import settings_from_file
from agv_nodes.world.concic2_dynamics import Concic2Dynamic, Concic2DynamicParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, build_path, layout_path, load_layout
from agv_nodes.world.settings import WorldParams
from agv_nodes.world.vehicles import Concic2

VEHICLES = {'kinematic': Concic2, 'dynamic': Concic2Dynamic}
PRESET = config_dir() / 'presets' / 'concic2_thesis.yaml'
THESIS = settings_from_file(RouteParams, PRESET, 'route_following')
STEP = 0.065  # m, the lateral step of the straight tape (7.3.3)
BAND = 0.005  # m, "back within 5 mm"
HALF_WINDOW = 0.1  # m, "the image window dimension (+-0.1 m)" (8.7); 80 % is 0.08 m (7.3.2)
# The thesis's "0.024 m/s^2" (7.3) put through Eq. 6.12 as printed (the gear ratio twice): the
# register then asks 9.9 x 0.024 wheel rev/s^2, 0.112 m/s^2 at the rim.
ACCELERATION_0024 = 9.9 * 0.024 * 2.0 * math.pi * 0.075


class TapeWorld(WorldCore):
    """The world core without its marker sensor, which a tape floor without cards leaves dark."""

    def _adc(self) -> dict[str, int]:
        return {}


class Executive:
    """Stand-in executive: camera mode, straight on at junctions."""

    node, period = 'executive', 0.05

    def on_record(self, *args: object) -> None:
        return None

    def tick(self, now: float) -> dict:
        return {'route_command': dict(mode='camera', srm_angle=0, junction='straight',
                                      manoeuvre=0)}


def strips(*pieces: tuple[list[float], float]) -> Layout:
    """Return tape_1991's floor with straight strips of its tape, no signs; start 1 m along."""
    lay = load_layout(layout_path('tape_1991'))
    width = lay.paths['circle'].width
    lay.paths = {f's{k}': build_path(f's{k}', start, [{'straight': length}], 0.02, lay.file,
                                     f's{k}', width=width)
                 for k, (start, length) in enumerate(pieces)}
    lay.signs = []
    lay.start_path, lay.start_at = 's0', 1.0
    return lay


def circle_floor() -> Layout:
    """Return tape_1991's R = 2.95 m circle without its road signs and their tapes (7.3.5)."""
    lay = load_layout(layout_path('tape_1991'))
    lay.paths = {'circle': lay.paths['circle']}  # a sign's patch and branches are tapes too
    lay.signs = []
    return lay


def thesis(**changes: object) -> SteeringParams:
    """Return the preset's steering settings with `changes` (the other readings)."""
    return replace(THESIS.steering, **changes)


def ring(radius: float) -> Layout:
    """Return tape_1991's floor with one tape circle of `radius` about the origin, no signs."""
    lay = load_layout(layout_path('tape_1991'))
    width = lay.paths['circle'].width
    lay.paths = {'ring': build_path('ring', [0.0, -radius, 0.0],
                                    [{'arc': radius, 'angle': 360}], 0.02, lay.file, 'ring',
                                    width=width)}
    lay.signs = []
    lay.start_path, lay.start_at = 'ring', 0.0
    return lay


def law(name: str, gain_d: float, gain_i: float, integral_form: str = 'per_frame',
        **options: float) -> SteeringParams:
    """Return the steering settings of a law with the thesis's gains and any of our options.

    `integral_form` per_frame adds G3 eps_d every frame as Eq. 5.8 is printed; with_dt
    multiplies by the frame time as Eq. 5.6 does.
    """
    return SteeringParams(law=name, gain_d=gain_d, gain_i=gain_i, integral_form=integral_form,
                          **options)


def truck(lay: Layout, vehicle: str, speed: float, steering: SteeringParams,
          pose: tuple[float, float, float] | None = None, acceleration: float | None = None,
          payload: float | None = None, image: ImageParams | None = None,
          encoder_time: float | None = None) -> tuple[Harness, WorldCore]:
    """Put the chosen CONCIC-II model on `lay` with route following in camera mode.

    `pose` (x, y, heading of the axle centre) overrides the layout's start; `acceleration`
    the drive's trapezoid (world concic2.acceleration), `payload` the dynamic model's load (kg;
    its default is the experiments' 250 lb), `image` the preset's image settings,
    `encoder_time` route following's drive_safety.encoder_time.
    """
    params = WorldParams(seed=2)
    if acceleration is not None:
        params.concic2 = replace(params.concic2, acceleration=acceleration)
    world = TapeWorld(lay, params)
    placed = world.vehicle.state
    if vehicle == 'dynamic' and payload is not None:
        world.vehicle = Concic2Dynamic(replace(
            Concic2DynamicParams.from_params(world.p.concic2), payload=payload))
    else:
        world.vehicle = VEHICLES[vehicle](world.p.concic2)
    s = world.vehicle.state
    s.x, s.y, s.heading = pose if pose is not None else (placed.x, placed.y, placed.heading)
    safety = (replace(THESIS.drive_safety, encoder_time=encoder_time) if encoder_time
              else THESIS.drive_safety)
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed,
                                  image=image or THESIS.image, steering=steering,
                                  drive_safety=safety))
    return Harness(world, [Executive(), route]), world


def camera_error(world: WorldCore) -> float:
    """Ground-truth offset (m) of the front window centre from the tape, + = window left."""
    s = world.vehicle.state
    lc = world.p.concic2.camera_distance
    return world.nearest_path_offset(s.x + lc * math.cos(s.heading),
                                     s.y + lc * math.sin(s.heading))


def trace(h: Harness, world: WorldCore, until: float
          ) -> list[tuple[float, float, float, float]]:
    """(time, camera x, camera y, camera error) every 50 ms until sim time `until`."""
    out = []
    lc = world.p.concic2.camera_distance
    while h.now < until:
        h.step()
        if world.sample % 17 == 0:
            s = world.vehicle.state
            out.append((h.now, s.x + lc * math.cos(s.heading), s.y + lc * math.sin(s.heading),
                        camera_error(world)))
    return out


@dataclass
class Result:
    """What one experiment gives, in the units of its row; nan where it does not apply."""

    overshoot: float = math.nan  # % of the step
    settle: float = math.nan  # s until within 5 mm for good
    steady: float = math.nan  # mm, mean |error| at the end
    worst: float = math.nan  # mm
    worst_at: float = math.nan  # s, when the worst error was
    held: bool = True  # the tape stayed in the window (no motor-off stop)


def settle_after(rows: list[tuple[float, float]], t0: float) -> float:
    """Return s from `t0` until |error| stays within BAND (inf if it ends outside)."""
    outside = [t for t, e in rows if abs(e) > BAND]
    if not outside:
        return 0.0
    return math.inf if outside[-1] >= rows[-1][0] - 1e-9 else outside[-1] - t0


def mean_abs(rows: list[tuple[float, float]], seconds: float) -> float:
    """Mean |error| (mm) over the last `seconds` of `rows`."""
    tail = [abs(e) for t, e in rows if t >= rows[-1][0] - seconds]
    return 1000.0 * sum(tail) / len(tail)


def step(vehicle: str, speed: float, steering: SteeringParams, **world: object) -> Result:
    """Follow a straight tape that steps 0.065 m sideways, met at cruise (7.3.3, Fig. 7.8a).

    `world`: truck()'s keywords (acceleration, payload, image).
    """
    at = 8.0  # m along x where the tape steps: the truck is at cruise and settled by then
    lay = strips(([-1.0, 0.0, 0.0], at + 1.0), ([at, STEP, 0.0], 40.0))
    h, world_core = truck(lay, vehicle, speed, steering, **world)
    # The set-off and the cruise to the step, then 10 s past it (at 0.2 m/s^2 or faster; the
    # slower "0.024" trapezoid reaches the step at cruise and leaves over 8 s past it).
    rows = trace(h, world_core, speed / 0.2 + at / speed + 10.0)
    # Past the step the window centre is STEP to the right of the tape: the error starts at
    # -STEP, and a positive error is an overshoot past the new tape.
    errors = [(t, y - STEP) for t, x, y, _e in rows if x > at]
    if not errors or not world_core.vehicle.pushing:
        return Result(held=False)
    return Result(overshoot=100.0 * max(0.0, max(e for _t, e in errors)) / STEP,
                  settle=settle_after(errors, errors[0][0]), steady=mean_abs(errors, 2.5))


def cruise(vehicle: str, speed: float, steering: SteeringParams, offset: float = 0.0,
           **world_kw: object) -> Result:
    """Set off from rest `offset` m left of a straight tape (7.3.2, 8.4.1: 5 mm at 0.79 m/s)."""
    h, world = truck(strips(([-1.0, 0.0, 0.0], 40.0)), vehicle, speed, steering,
                     (0.0, offset, 0.0), **world_kw)
    rows = [(t, e) for t, _x, _y, e in trace(h, world, 25.0)]
    at, worst = max(rows, key=lambda r: abs(r[1]))
    return Result(settle=settle_after(rows, 0.0), steady=mean_abs(rows, 10.0),
                  worst=1000.0 * abs(worst), worst_at=at, held=world.vehicle.pushing)


def recovery(vehicle: str, offset: float, angle_deg: float, steering: SteeringParams,
             **world_kw: object) -> Result:
    """Start `offset` m off the tape at the window and `angle_deg` off it (7.3.2, Fig. 7.7)."""
    lc = 0.64
    heading = math.radians(angle_deg)
    pose = (1.0 - lc * math.cos(heading), offset - lc * math.sin(heading), heading)
    h, world = truck(strips(([-1.0, 0.0, 0.0], 40.0)), vehicle, 0.471, steering, pose,
                     **world_kw)
    rows = [(t, e) for t, _x, _y, e in trace(h, world, 20.0)]
    held = world.vehicle.pushing
    return Result(settle=settle_after(rows, 0.0) if held else math.nan,
                  steady=mean_abs(rows, 2.5) if held else math.nan,
                  worst=1000.0 * max(abs(e) for _t, e in rows), held=held)


def circle(vehicle: str, speed: float, steering: SteeringParams, radius: float = 0.0,
           **world_kw: object) -> Result:
    """Follow a circle from rest: error after 20 s (7.3.5, Fig. 7.10; Table 6.1).

    `radius` 0: tape_1991's R = 2.95 m circle; else a circle of that radius, the truck set down
    with its window centre on the tape (the axle sqrt(R^2 - L_c^2) from the centre, or on it
    when R < L_c, where no pose puts the window on the tape).
    """
    if radius:
        lc = world_kw.pop('camera', 0.64)
        axle = math.sqrt(max(radius * radius - lc * lc, 0.0))
        h, world = truck(ring(radius), vehicle, speed, steering, (0.0, -axle, 0.0), **world_kw)
    else:
        h, world = truck(circle_floor(), vehicle, speed, steering, **world_kw)
    rows = [(t, e) for t, _x, _y, e in trace(h, world, 30.0)]
    late = [(t, e) for t, e in rows if t >= 20.0]
    if not world.vehicle.pushing:
        return Result(worst=1000.0 * max(abs(e) for _t, e in rows), held=False)
    return Result(steady=mean_abs(late, 10.0), worst=1000.0 * max(abs(e) for _t, e in late),
                  held=True)


def drive(vehicle: str) -> dict[str, float]:
    """Open-loop drive figures of one model, stepped at the world's sub-step.

    speed overshoot: % past 0.63 m/s after a step from rest; to full speed: s from rest to 99 %
    of 0.785 m/s; yaw overshoot and t63: a 0.06 m/s differential step at 0.47 m/s cruise (% past,
    and s to 63 % of, (v2 - v1) / L), through the trapezoid and, for the servo loop alone, with
    the trapezoid's acceleration at 30 m/s^2 (the profile a step); yaw ratio: the mean yaw rate
    2-3 s after it over (v2 - v1) / L; stop: mm from motor off at 0.157 m/s.
    """
    dt = 1.0 / 340.0 / 4.0
    truck = WorldParams().concic2

    def steps(v: Concic2 | Concic2Dynamic, seconds: float) -> list[tuple[float, float, float]]:
        out = []
        for k in range(1, int(round(seconds / dt)) + 1):
            v.step(dt)
            out.append((k * dt, *v.wheel_speeds()))
        return out

    def full_speed(acceleration: float) -> float:
        v = VEHICLES[vehicle](replace(truck, acceleration=acceleration))
        v.set_wheels(0.785, 0.785, True)
        return next(t for t, a, b in steps(v, 12.0) if 0.5 * (a + b) >= 0.99 * 0.785)

    def differential(acceleration: float) -> tuple[float, float, float]:
        v = VEHICLES[vehicle](replace(truck, acceleration=acceleration))
        v.set_wheels(0.47, 0.47, True)
        steps(v, 4.0)
        v.set_wheels(0.44, 0.50, True)
        target = 0.06 / truck.wheel_span
        yaw = [(t, (b - a) / truck.wheel_span / target) for t, a, b in steps(v, 3.0)]
        late = [w for t, w in yaw if t > 2.0]
        return (100.0 * (max(w for _t, w in yaw) - 1.0),
                next(t for t, w in yaw if w >= 0.632), sum(late) / len(late))

    v = VEHICLES[vehicle](truck)
    v.set_wheels(0.63, 0.63, True)
    peak = max(0.5 * (a + b) for _t, a, b in steps(v, 5.0))
    yaw, t63, ratio = differential(truck.acceleration)
    _o, servo, _r = differential(30.0)
    v = VEHICLES[vehicle](truck)
    v.set_wheels(0.157, 0.157, True)
    steps(v, 3.0)
    x0 = v.state.distance
    v.set_wheels(0.0, 0.0, False)
    steps(v, 1.0)
    return {'speed': 100.0 * (peak / 0.63 - 1.0), 'full': full_speed(truck.acceleration),
            'full_0024': full_speed(ACCELERATION_0024), 'yaw': yaw, 't63': t63,
            'servo': servo, 'ratio': ratio, 'stop': 1000.0 * (v.state.distance - x0)}


DRIVE = (('speed step 0 to 0.63 m/s: overshoot (%)', '1 (7.5.2.1)', 'speed', 1),
         ('rest to 0.785 m/s, world concic2.acceleration 0.3 m/s^2 (s)',
          'less than 7 (7.3.2)', 'full', 2),
         ('the same, the "0.024" read through Eq. 6.12 (0.112 m/s^2) (s)',
          'less than 7 (7.3.2)', 'full_0024', 2),
         ('differential step at 0.47 m/s: yaw-rate overshoot (%)',
          'wheel loop tuned critically damped, 5 (C.2.3.5)', 'yaw', 1),
         ('differential step through the 0.3 m/s^2 trapezoid: time to 63 % (s)',
          '-', 't63', 3),
         ('differential step, the servo loop alone (profile a step): time to 63 % (s)',
          '4 cycles of 40-60 ms: 0.16-0.24 (6.3.8; the cycle 6.3.10, 7.5.1.6)',
          'servo', 3),
         ('differential step: steady yaw rate / (v2 - v1) / L', '1', 'ratio', 4),
         ('motor off at 0.157 m/s: stopping distance (mm)', '5 (7.3.4, Fig. 7.9)', 'stop', 1))


def payload(vehicle: str, speed: float, steering: SteeringParams, offset: float
            ) -> tuple[Result, Result] | None:
    """Return the start of cruise() with the 250 lb payload and without (7.3.2, Fig. 7.6).

    None for the kinematic model, which has no mass.
    """
    if vehicle != 'dynamic':
        return None
    return (cruise(vehicle, speed, steering, offset),
            cruise(vehicle, speed, steering, offset, payload=0.0))
