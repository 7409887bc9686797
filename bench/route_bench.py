"""Route-following benchmark: guide wire on demo_1983, SRM landings, camera guidance.

Run: .venv/bin/python bench/route_bench.py [wire] [srm] [circle] [step] [recovery] [stop]
     [junction]


- Guide wire: lateral error of the sensor point along the demo route (straights and the
  R = 2.5 m arc) at 0.7 and 1.0 m/s (goal: +-1 cm; the thesis text states no tolerance).
- SRM: landing offset on wire B 10 s after leaving wire A at L1, by angle and speed.
- Camera (Rajagopalan 1991, CONCIC-II on tape): steady error on the R = 2.95 m circle, and a
  0.065 m lateral step of a straight tape at 0.31-0.79 m/s: overshoot, 5 mm settling time,
  steady error (thesis: ~10 % overshoot, back within 5 mm in ~3 s at 0.63 m/s, 5 mm steady).
- Junction: turning onto a branch of junction_1991's cross (Rajagopalan 1991, App. F.6) by
  cruise speed.

"""

from __future__ import annotations

import math
import sys

from agv_nodes.harness import Harness
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams, SteeringParams
from agv_nodes.traction.core import TractionCore
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import build_path, layout_path, load_layout
from agv_nodes.world.settings import WorldParams


class Executive:
    node, period = 'executive', 0.05

    def __init__(self, demand: int = 0, mode: str = 'follow_wire',
                 junction: str = 'straight') -> None:
        self.demand, self.mode, self.manoeuvre, self.angle = demand, mode, 0, 0
        self.junction = junction

    def on_record(self, *args):
        return None

    def tick(self, now):
        out = {'route_command': dict(mode=self.mode, srm_angle=self.angle,
                                     junction=self.junction, manoeuvre=self.manoeuvre)}
        if self.mode != 'camera':
            out['traction_command'] = dict(manual=0, manual_speed=0, reverse=0,
                                           demand=self.demand if now > 0.3 else 0,
                                           executive_priority=0)
        return out


def wire_errors(demand: int) -> tuple[float, float, float]:
    world = WorldCore(load_layout(layout_path('demo_1983')), WorldParams(seed=3))
    route = RouteCore()
    h = Harness(world, [Executive(demand), TractionCore(), route])
    worst = rms = n = 0.0
    while route.state != 'lost' and h.now < 60:
        h.step()
        if h.now > 3 and world.sample % 17 == 0:
            e = abs(world.nearest_path_offset(*world.vehicle.sensor_point))
            worst, rms, n = max(worst, e), rms + e * e, n + 1
    return worst * 1000, math.sqrt(rms / n) * 1000, world.vehicle.state.speed


def srm(angle: int, demand: int) -> tuple[str, float, float]:
    world = WorldCore(load_layout(layout_path('demo_1983')), WorldParams(seed=3))
    ex, route = Executive(demand), RouteCore()
    h = Harness(world, [ex, TractionCore(), route])
    start = landed = None
    started = False
    while h.now < 150:
        h.step()
        sx, sy = world.vehicle.sensor_point
        if start is None and sy > 4.5 and sx < 8.5:
            ex.mode, ex.manoeuvre, ex.angle, start = 'srm', 1, angle, h.now
        if start is not None and route.state in ('srm_running', 'wire_found'):
            started = True
        if started and route.mode == 'follow_wire' and landed is None:
            landed = h.now
        if landed is not None and h.now > landed + 5:
            break
    _sx, sy = world.vehicle.sensor_point
    took = (landed - start) if landed is not None and start is not None else float('nan')
    return route.state, took, (sy - 4.0) * 1000


CAMERA_AHEAD = 0.64  # m from the CONCIC-II's reference point to the camera's view centre


def camera_point(world: WorldCore) -> tuple[float, float]:
    """Where the camera looks (the thesis measures the guidance error there)."""
    s = world.vehicle.state
    return (s.x + CAMERA_AHEAD * math.cos(s.heading),
            s.y + CAMERA_AHEAD * math.sin(s.heading))


def camera_truck(world: WorldCore, speed: float, law: str = 'p', gain_i: float = 0.0,
                 gain_theta: float = 0.0, schedule: float = 0.0) -> tuple[Harness, RouteCore]:
    """Put the CONCIC-II on `world`, route following in camera mode with the given law.

    'pi_b' is PI whose integral gathers only within 10 mm of the tape (the integral_band
    option).
    """
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed,
                                  steering=SteeringParams(law=law[:2], gain_i=gain_i,
                                                          gain_theta=gain_theta,
                                                          schedule_speed=schedule,
                                                          integral_band=0.01 if law == 'pi_b'
                                                          else 0.0)))
    return Harness(world, [Executive(mode='camera'), route]), route


def camera_trace(h: Harness, world: WorldCore, until: float) -> list[tuple[float, float, float]]:
    """(time, camera x, camera y) every 17 samples (50 ms) until sim time `until`."""
    trace = []
    while h.now < until:
        h.step()
        if world.sample % 17 == 0:
            trace.append((h.now, *camera_point(world)))
    return trace


def tape(*strips: tuple[str, list[float], float]):
    """Return tape_1991 with its tape replaced by straight strips and no road signs.

    Each strip is (name, [x, y, heading], length); the vehicle starts 1 m along the first.
    """
    lay = load_layout(layout_path('tape_1991'))
    width = lay.paths['circle'].width
    lay.paths = {name: build_path(name, start, [{'straight': length}], 0.02, lay.file, name,
                                  width=width) for name, start, length in strips}
    lay.signs = []
    lay.start_path, lay.start_at = strips[0][0], 1.0
    return lay


def camera_circle(law: str, gain_i: float, speed: float, gain_theta: float = 0.0,
                  schedule: float = 0.0) -> float:
    world = WorldCore(load_layout(layout_path('tape_1991')), WorldParams(seed=2))
    h, _route = camera_truck(world, speed, law, gain_i, gain_theta, schedule)
    h.run(20.0)
    errors = []
    for _ in range(20):
        h.run(0.5)
        errors.append(world.nearest_path_offset(*camera_point(world)))
    return 1000 * sum(abs(e) for e in errors) / len(errors)


def camera_step(law: str, gain_i: float, speed: float, gain_theta: float = 0.0,
                schedule: float = 0.0) -> tuple[float, float, float]:
    """Follow a tape that jumps 0.065 m sideways: overshoot %, 5 mm settle (s), steady mm."""
    step_at = 6.0
    world = WorldCore(tape(('a', [-1.0, 0.0, 0.0], step_at + 2.0),
                           ('b', [step_at + 1.0, 0.065, 0.0], 30.0)), WorldParams(seed=2))
    h, _route = camera_truck(world, speed, law, gain_i, gain_theta, schedule)
    trace = [(t, cy - 0.065) for t, cx, cy in camera_trace(h, world, 40.0)
             if cx > step_at + 1.0]
    t0 = trace[0][0]
    overshoot = 100 * max(0.0, max(e for _t, e in trace)) / 0.065
    outside = [t for t, e in trace if abs(e) > 0.005]
    settle = (outside[-1] - t0) if outside else 0.0
    steady = 1000 * sum(abs(e) for _t, e in trace[-50:]) / 50
    return overshoot, settle, steady


def camera_recovery(law: str, gain_i: float, gain_theta: float, speed: float, offset: float,
                    angle_deg: float, schedule: float = 0.0) -> tuple[float, float, float]:
    """Start `offset` m beside the tape (at the camera) and `angle_deg` off its heading.

    Rajagopalan 1991, 7.6 (Fig. 7.7) starts at -0.08 m and 40 deg at 0.471 m/s. Return the worst
    |error| (mm), time to stay within 5 mm (s), steady error (mm); nan when the tape is lost.
    """
    world = WorldCore(tape(('a', [-1.0, 0.0, 0.0], 30.0)), WorldParams(seed=2))
    s = world.vehicle.state
    s.heading = math.radians(angle_deg)
    s.x = 1.0 - CAMERA_AHEAD * math.cos(s.heading)
    s.y = offset - CAMERA_AHEAD * math.sin(s.heading)
    h, route = camera_truck(world, speed, law, gain_i, gain_theta, schedule)
    trace = [(t, cy) for t, _cx, cy in camera_trace(h, world, 20.0)]
    if route.state == 'lost' or not route.motor_on:
        return float('nan'), float('nan'), float('nan')
    outside = [t for t, e in trace if abs(e) > 0.005]
    worst = 1000 * max(abs(e) for _t, e in trace)
    steady = 1000 * sum(abs(e) for _t, e in trace[-50:]) / 50
    return worst, (outside[-1] if outside else 0.0), steady


def camera_stop(speed: float) -> tuple[float, float]:
    """Run to the tape's end: four absent frames turn the motors off (Rajagopalan 1991, 7.3.4).

    Return the distance coasted after motor-off (mm) and the distance from the tape's end to
    rest (mm), both at the camera.
    """
    world = WorldCore(tape(('a', [-1.0, 0.0, 0.0], 4.0)), WorldParams(seed=2))
    h, route = camera_truck(world, speed)
    off_x = None
    while h.now < 60:
        h.step()
        cx, _cy = camera_point(world)
        if off_x is None and h.now > 2 and not route.motor_on:
            off_x = cx
        if off_x is not None and world.vehicle.state.speed == 0.0:
            return 1000 * (cx - off_x), 1000 * (cx - 3.0)  # the tape runs -1 .. 3 m
    return float('nan'), float('nan')


def camera_junction(junction: str, speed: float) -> dict[str, float | str]:
    """Take a branch of junction_1991's R2 crossing (Rajagopalan 1991, App. F.6).

    Return where the spin began, the heading it ended on, the camera's offset on the branch
    then and over the next 3 s.
    """
    lay = load_layout(layout_path('junction_1991'))
    world = WorldCore(lay, WorldParams(seed=3))
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed))
    h = Harness(world, [Executive(mode='camera', junction=junction), route])
    crossing = lay.paths['main'].pose_at(lay.signs[0]['at'])
    branch = lay.paths[f'sign0_{junction}']
    want = crossing[2] + (math.pi / 2 if junction == 'left' else -math.pi / 2)
    out: dict[str, float | str] = {'spin_at': math.nan, 'resumed': math.nan}
    seen = resumed = None
    offsets = []
    while h.now < 40.0:
        h.step()
        s = world.vehicle.state
        if seen is None and route.turn_phase:
            seen = h.now
        if route.turn_phase == 'spin' and math.isnan(out['spin_at']):
            along = (s.x - crossing[0]) * math.cos(crossing[2]) + \
                (s.y - crossing[1]) * math.sin(crossing[2])
            out['spin_at'] = along * 1000.0
        if seen is not None and resumed is None and not route.turn_phase:
            resumed = h.now
            out['resumed'] = resumed - seen
            out['heading'] = math.degrees(s.heading - want)
        if resumed is not None:
            if h.now > resumed + 3.0:
                break
            if world.sample % 17 == 0:
                offsets.append(abs(branch.project(*camera_point(world))[1]) * 1000.0)
    out['first'] = offsets[0] if offsets else math.nan
    out['worst'] = max(offsets, default=math.nan)
    out['last'] = offsets[-1] if offsets else math.nan
    out['state'] = route.state
    return out


# (law, G_i, G_theta, schedule speed): the thesis's P and PI, then with orientation feedback,
# the 1/speed gain schedule and (pi_b) the integral gathered only within 10 mm of the tape
# (modern options, route_following parameters steering.gain_theta, steering.schedule_speed,
# steering.integral_band)
LAWS = (('p', 0.0, 0.0, 0.0), ('pi', 0.07, 0.0, 0.0), ('p', 0.0, 0.3, 0.0),
        ('p', 0.0, 0.4, 0.63), ('pi_b', 0.07, 0.4, 0.63))


def law_cells(law: str, gain_theta: float, schedule: float) -> str:
    """Return the first three cells of a camera-law row: law, G_theta, schedule speed."""
    return f'| {law} | {gain_theta} | {schedule or "-"} |'


def main() -> int:
    only = sys.argv[1:] or ['wire', 'srm', 'circle', 'step', 'recovery', 'stop', 'junction']
    if 'wire' in only:
        print('Guide wire on demo_1983 (sensor point to the wire)\n')
        print('| demand (%) | speed (m/s) | max error (mm) | rms error (mm) |\n|---|---|---|---|')
        for demand in (55, 80):
            worst, rms, speed = wire_errors(demand)
            print(f'| {demand} | {speed:.2f} | {worst:.1f} | {rms:.1f} |', flush=True)
    if 'srm' in only:
        print('\nSRM from wire A at L1 onto wire B (offset 5 s after the capture ends)\n')
        print('| angle (deg) | speed | state | leave to following (s) | offset on B (mm) |\n'
              '|---|---|---|---|---|')
        for angle in (10, 15, 20):
            for demand, label in ((27, '0.3 m/s'), (55, '0.7 m/s')):
                state, took, offset = srm(angle, demand)
                print(f'| {angle} | {label} | {state} | {took:.1f} | {offset:+.1f} |',
                      flush=True)
    if 'circle' in only:
        print('\nCamera guidance, circle R = 2.95 m (mean |eps| at the camera, after 20 s)\n')
        print('| law | G_theta | schedule (m/s) | speed (m/s) | mean error (mm) |\n'
              '|---|---|---|---|---|')
        for law, gain_i, gain_theta, schedule in LAWS:
            for speed in (0.31, 0.63, 0.79):
                e = camera_circle(law, gain_i, speed, gain_theta, schedule)
                print(f'{law_cells(law, gain_theta, schedule)} {speed} | {e:.1f} |', flush=True)
    if 'step' in only:
        print('\nCamera guidance, 0.065 m step of a straight tape (G_theta: orientation gain; '
              'the thesis fed none back)\n')
        print('| law | G_theta | schedule (m/s) | speed (m/s) | overshoot (%) | within 5 mm '
              'after (s) | steady error (mm) |\n|---|---|---|---|---|---|---|')
        for law, gain_i, gain_theta, schedule in LAWS:
            for speed in (0.31, 0.47, 0.63, 0.79):
                o, t, e = camera_step(law, gain_i, speed, gain_theta, schedule)
                print(f'{law_cells(law, gain_theta, schedule)} {speed} | {o:.1f} | {t:.2f} | '
                      f'{e:.1f} |', flush=True)
    if 'recovery' in only:
        print('\nCamera guidance from an initial error (Rajagopalan 1991, 7.6: -0.08 m and '
              '40 deg at 0.471 m/s)\n')
        print('| law | G_theta | schedule (m/s) | offset (m) | angle (deg) | worst error (mm) '
              '| within 5 mm after (s) | steady error (mm) |\n|---|---|---|---|---|---|---|---|')
        for law, gain_i, gain_theta, schedule in LAWS:
            for offset, angle in ((-0.08, 40.0), (-0.08, -40.0), (0.08, -40.0)):
                w, t, e = camera_recovery(law, gain_i, gain_theta, 0.471, offset, angle,
                                          schedule)
                print(f'{law_cells(law, gain_theta, schedule)} {offset:+.2f} | {angle:+.0f} | '
                      f'{w:.0f} | {t:.2f} | {e:.1f} |', flush=True)
    if 'stop' in only:
        print('\nCamera guidance: motor-off stop at the end of the tape (thesis 7.3.4: 5 mm '
              'from 0.16 m/s; the coast-down is calibrated to it, the detection is not)\n')
        print('| speed (m/s) | coasted after motor-off (mm) | tape end to rest (mm) |\n'
              '|---|---|---|')
        for speed in (0.16, 0.31, 0.47):
            coast, past = camera_stop(speed)
            print(f'| {speed} | {coast:.1f} | {past:.0f} |', flush=True)
    if 'junction' in only:
        print('\nCamera guidance: turning at the R2 crossing of junction_1991 (App. F.6: slow '
              'down, stop with the axle centre over the crossing, spin a quarter turn, follow '
              'the branch; PI law)\n')
        print('| branch | cruise (m/s) | axle past the crossing at the spin (mm) | seen to '
              'following (s) | heading error after (deg) | camera offset on the branch: at '
              'once / worst / after 3 s (mm) | state |\n|---|---|---|---|---|---|---|')
        for junction in ('left', 'right'):
            for speed in (0.31, 0.47, 0.63, 0.79):
                r = camera_junction(junction, speed)
                print(f"| {junction} | {speed} | {r['spin_at']:+.0f} | {r['resumed']:.1f} | "
                      f"{r.get('heading', math.nan):+.1f} | {r['first']:.1f} / "
                      f"{r['worst']:.1f} / {r['last']:.1f} | {r['state']} |", flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
