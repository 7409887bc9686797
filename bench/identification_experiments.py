"""The experiments of the identification bench (Rajagopalan 1991, 7.5.2, E3-E7).

The camera truck on the simulated world in lock step (the world core with each CONCIC-II
model, the route-following core in camera mode): drive logs every frame's eps_d, eps_theta and
wheel_odometry counters beside the ground truth; reconstruct places the truck and the points P
off line from those logs; e3-e7 fit them on the straight tapes, the R = 2.95 m circle and the
ellipse (ellipse_floor, its floor) and measure the reconstruction's errors. Their tables and
notes are identification_report.py's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import statistics

from concic2_thesis_bench import VEHICLES, Executive, TapeWorld, circle_floor, strips
from identification_sims import DT, ChordOdometry, Point, ellipse_errors, ellipse_points, settle
import numpy as np

from agv_nodes.harness import Harness
from agv_nodes.odometry import counter_step
from agv_nodes.route_following.camera_guidance import Validity
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.track_geometry.criteria import desired_from_circle, desired_offsets
from agv_nodes.track_geometry.fitting import ConicFit, LineFit
from agv_nodes.track_geometry.osculating import osculating_implicit
from agv_nodes.track_geometry.pose import PoseIntegrator, track_point
from agv_nodes.track_geometry.settings import IdentificationParams
from agv_nodes.track_geometry.track_fitter import TrackFitter
from agv_nodes.world.layout import Layout, Path2D
from agv_nodes.world.settings import WorldParams

E_RADIUS = 2.95  # m, the thesis's tape circle (7.5.2.5)
E4_ANGLE = 0.6  # rad, the straight tape in the floor frame (7.5.2.4)
E7_AXES = (3.40, 2.76)  # m, the ellipse's axes (7.5.2.6)
SET_OFF = 0.2  # m/s^2, route following's set-off ramp (its default)


# -- the experiments: the camera truck in lock step, then off line --------------------------------

@dataclass
class Frame:
    """One camera frame's log: what the truck knew, and the ground truth beside it."""

    t: float
    eps_d: float
    eps_theta: float
    valid: bool  # a fresh frame with the tape in view
    left_mm: int  # wheel_odometry's wrapping counters at the frame
    right_mm: int
    pose: tuple[float, float, float]  # true (x, y, heading) of the axle centre O
    truth_d: float  # true eps_d at the window centre


@dataclass
class Run:
    """A logged run and its off-line reconstruction: (P, odometric O, frame) per sample."""

    frames: list[Frame]
    start: tuple[float, float, float]
    held: bool  # the route core still followed the tape at the end
    tape: Path2D
    samples: list[tuple[Point, tuple[float, float, float], Frame]] = field(init=False)

    def __post_init__(self) -> None:
        self.samples = reconstruct(self)

    def upto(self, n: int | None = None, distance: float | None = None) -> list:
        """Return the first `n` samples, or those within `distance` m of travel."""
        out = self.samples[:n]
        return out if distance is None else [r for r in out if r[0].s <= distance]


def drive(lay: Layout, vehicle: str, speed: float, seconds: float) -> Run:
    """Run the camera truck on `lay` for `seconds` of sim time, logging every frame."""
    world = TapeWorld(lay, WorldParams(seed=2))
    placed = world.vehicle.state
    world.vehicle = VEHICLES[vehicle](world.p.concic2)
    s = world.vehicle.state
    s.x, s.y, s.heading = placed.x, placed.y, placed.heading
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed))
    h = Harness(world, [Executive(), route])
    lc = route.p.turning.camera_ahead
    frames, counters, seen = [], (0, 0), None
    start = (s.x, s.y, s.heading)
    while h.now < seconds:
        out = h.step()
        if (odo := out['records'].get('wheel_odometry')) is not None:
            counters = (odo['left_distance'], odo['right_distance'])
        if not out['frames']:
            continue
        m = route.cam.measurement
        fresh = m is not None and m is not seen
        seen = m
        cx, cy = s.x + lc * math.cos(s.heading), s.y + lc * math.sin(s.heading)
        truth = world.camera.truth(cx, cy, s.heading)
        frames.append(Frame(h.now, m.eps_d if fresh else 0.0, m.eps_theta if fresh else 0.0,
                            fresh and m.validity is Validity.NORMAL, *counters,
                            (s.x, s.y, s.heading), truth[0] if truth else math.nan))
    return Run(frames, start, route.cam.state == 'following', next(iter(lay.paths.values())))


def reconstruct(run: Run, rule: str = 'trapezoid'
                ) -> list[tuple[Point, tuple[float, float, float], Frame]]:
    """Odometric pose (`rule`, wheel travel per frame) and P for each valid moving frame."""
    p = RouteParams().steering
    lc = RouteParams().turning.camera_ahead
    x, y, heading = run.start
    fit = PoseIntegrator(p.wheel_span, rule, x=x, y=y, heading=heading)
    out, before = [], (0, 0, 0.0)  # the counters start at 0 with the world
    for f in run.frames:
        if f.t > before[2]:
            fit.update_travel(counter_step(before[0], f.left_mm) / 1000.0,
                              counter_step(before[1], f.right_mm) / 1000.0, f.t - before[2])
        before = (f.left_mm, f.right_mm, f.t)
        if f.valid and fit.distance > 0.0:
            x, y, theta = track_point(*fit.pose, lc, f.eps_d, f.eps_theta)
            out.append((Point(x, y, theta, fit.distance), fit.pose, f))
    return out


def deviation(run: Run, samples: list) -> float:
    """Largest distance (m) of the reconstructed P from the tape's centreline."""
    return max(abs(run.tape.project(p.x, p.y)[1]) for p, _o, _f in samples)


def odometry_error(samples: list) -> tuple[float, float]:
    """Largest error (m) of the odometric O along and across the true heading."""
    along = across = 0.0
    for _p, o, f in samples:
        dx, dy, h = o[0] - f.pose[0], o[1] - f.pose[1], f.pose[2]
        along = max(along, abs(math.cos(h) * dx + math.sin(h) * dy))
        across = max(across, abs(-math.sin(h) * dx + math.cos(h) * dy))
    return along, across


def chord_error(run: Run, samples: list) -> tuple[float, float]:
    """Largest errors (m) with ChordOdometry in place of the trapezoid, at the samples' frames.

    (distance of O from the true O, distance of P from the tape's centreline)
    """
    chord = ChordOdometry(RouteParams().steering.wheel_span, *run.start)
    lc = RouteParams().turning.camera_ahead
    at, before, worst, off = {id(f) for *_, f in samples}, (0, 0), 0.0, 0.0
    for f in run.frames:
        x, y, h = chord.update(counter_step(before[0], f.left_mm) / 1000.0,
                               counter_step(before[1], f.right_mm) / 1000.0)
        before = (f.left_mm, f.right_mm)
        if id(f) in at:
            worst = max(worst, math.hypot(x - f.pose[0], y - f.pose[1]))
            px, py, _ = track_point(x, y, h, lc, f.eps_d, f.eps_theta)
            off = max(off, abs(run.tape.project(px, py)[1]))
    return worst, off


def camera_error(samples: list) -> float:
    """RMS (m) of the analyser's eps_d against the ground truth."""
    return math.sqrt(sum((f.eps_d - f.truth_d) ** 2 for *_, f in samples) / len(samples))


def set_off(speed: float) -> float:
    """Seconds the set-off ramp loses against cruising from the start."""
    return speed / SET_OFF / 2.0


def e3(vehicle: str, speed: float) -> dict:
    """Drive a straight tape along x, 9 m of travel from rest (7.5.2.3)."""
    run = drive(strips(([-1.0, 0.0, 0.0], 12.0)), vehicle, speed, 9.0 / speed + set_off(speed)
                + 1.0)
    samples = run.upto(distance=9.0)
    return {'held': run.held, 'deviation': deviation(run, samples),
            'odometry': odometry_error(samples), 'camera': camera_error(samples)}


def e4(vehicle: str, n: int) -> dict:
    """Drive a straight tape through the origin at 0.6 rad, 0.31 m/s (7.5.2.4); y = m x + c."""
    c, s = math.cos(E4_ANGLE), math.sin(E4_ANGLE)
    speed = 0.31
    run = drive(strips(([-c, -s, math.degrees(E4_ANGLE)], 30.0)), vehicle, speed,
                n * DT + set_off(speed) + 1.0)
    slope = math.tan(E4_ANGLE)
    line, errors, at = LineFit(form='plain'), [], {}
    for k, (p, _o, _f) in enumerate(run.upto(n)):
        line.add(p.x, p.y, p.s)
        m = line.slope_intercept
        errors.append(None if m is None else abs(m[0] / slope - 1.0))
        if k + 1 in (200, n):
            at[k + 1] = (abs(m[0] / slope - 1.0), abs(m[1]), p.s)
    samples = run.upto(n)
    return {'held': run.held, 'at': at, 'converged': settle(errors), 'n': len(samples),
            'deviation': deviation(run, samples), 'odometry': odometry_error(samples)}


def e5(vehicle: str, n: int) -> dict:
    """Drive the R = 2.95 m circle at 0.63 m/s (7.5.2.5); the conic model; E6 from it."""
    speed = 0.63
    run = drive(circle_floor(), vehicle, speed, n * DT + set_off(speed) + 1.0)
    samples = run.upto(n)
    # All the data since the start, as the thesis fitted (route following's default is a
    # sliding window, for routes of several shapes).
    fit, fitter = ConicFit(), TrackFitter(IdentificationParams(model='conic', memory='all'))
    errors, radius = [], {}
    for k, (p, _o, _f) in enumerate(samples):
        fit.add(p.x, p.y, p.theta, p.s)
        fitter.add(p.x, p.y, p.theta, p.s)
        c = fit.circle()
        errors.append(None if c is None else abs(c[2] / E_RADIUS - 1.0))
        if k + 1 in (600, 800, 900):
            radius[k + 1] = c[2]
    cx, cy, r = fit.circle()
    p, o, _ = samples[-1]
    osc = osculating_implicit(fitter.implicit(), p.x, p.y, p.theta)
    turned = [f.pose[2] - run.start[2] for *_, f in samples]
    return {'held': run.held, 'n': len(samples), 'radius': radius, 'final': r,
            'centre': math.hypot(cx, cy), 'converged': settle(errors),
            'laps600': turned[599] / (2 * math.pi) if len(samples) >= 600 else None,
            'deviation': deviation(run, samples), 'odometry': odometry_error(samples),
            'camera': camera_error(samples),
            'chord': chord_error(run, samples),
            'desired_fit': desired_offsets(r, 1),
            'desired_osc': desired_from_circle(osc, *o),
            'osc_radius': osc.radius,
            'measured': tuple(statistics.fmean(v) for v in zip(
                *[(f.eps_d, f.eps_theta) for *_, f in samples[-200:]], strict=True))}


def ellipse_floor(a: float, b: float) -> Layout:
    """tape_1991's floor with one tape, the ellipse of semi-axes a, b about the origin.

    The layouts build paths from straight and arc segments only, so the polyline is made
    here: points at most 2 cm apart (the layouts' step), from (0, -b) counter-clockwise, the
    tangent's heading at each, unwrapped; the start is 0.5 m along it.
    """
    lay = circle_floor()
    width = lay.paths['circle'].width
    phi = np.linspace(-math.pi / 2, 1.5 * math.pi, math.ceil(2 * math.pi * max(a, b) / 0.02) + 1)
    points = np.stack([a * np.cos(phi), b * np.sin(phi)], axis=1)
    points[-1] = points[0]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    headings = np.unwrap(np.arctan2(b * np.cos(phi), -a * np.sin(phi)))
    lay.paths = {'ellipse': Path2D('ellipse', points, s, headings, width, closed=True)}
    lay.start_path, lay.start_at = 'ellipse', 0.5
    return lay


def e7(vehicle: str, a: float, b: float, n: int) -> dict:
    """Drive the ellipse of semi-axes a, b at 0.63 m/s (7.5.2.6); the conic model."""
    speed = 0.63
    run = drive(ellipse_floor(a, b), vehicle, speed, n * DT + set_off(speed) + 1.0)
    samples = run.upto(n)
    points = (p for p, _o, _f in samples)
    at = tuple(k for k in (400, 600, 800) if k <= len(samples))
    return {'held': run.held, 'n': len(samples), 'at': ellipse_errors(points, a, b, at),
            'deviation': deviation(run, samples), 'odometry': odometry_error(samples),
            'chord': chord_error(run, samples),
            'exact': ellipse_errors(ellipse_points(n, a, b, speed * DT, start=-math.pi / 2),
                                    a, b, at)}
