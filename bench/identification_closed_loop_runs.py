"""E8's runs: one truck on one course under one law, measured in lock step against ground truth.

The world core, the route-following core in camera mode and a stand-in executive, seeded, as
test/test_route_feed_forward.py builds them. bench/identification_closed_loop.py holds the grid,
the goals and the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import tempfile
import time

from concic2_best_bench import OURS
from concic2_thesis_bench import TapeWorld, circle_floor

from agv_nodes.harness import CameraLegScript, Harness
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.track_geometry.settings import FeedForwardParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

R = 2.95  # m: the thesis's circle (7.3.5), tape_1991's
LEAD = 4.0  # m of straight before the first curve and after the last
START = 0.3  # m along the tape where the window starts (a layout's start places it)
WIDTH = 0.058  # m of tape, as the test's layouts
FINISH = 3.0  # m along the last straight the axle must reach: the course completed
FRAME = 17  # world samples (340 Hz) per ground-truth sample: 50 ms, a camera frame
ENTER, BEFORE, AFTER = 2.0, 1.0, 2.0  # m of the spans: into a curve; before and past its end
ARC = math.pi * R / 2.0  # m of a 90 degree arc
# Segments (layout.py: straight m, or arc radius with angle deg, + = left) and the curves'
# (start, end) m along the tape.
COURSES: dict[str, tuple[str, list[tuple[float, float]]]] = {
    'circle': (f'{{straight: {LEAD}}}, {{arc: {R}, angle: 180.0}}, {{straight: {LEAD}}}',
               [(LEAD, LEAD + 2.0 * ARC)]),
    's_bend': (f'{{straight: {LEAD}}}, {{arc: {R}, angle: 90.0}}, {{arc: {R}, angle: -90.0}}, '
               f'{{straight: {LEAD}}}', [(LEAD, LEAD + ARC), (LEAD + ARC, LEAD + 2.0 * ARC)]),
}
# RouteParams keywords of each law. Every law reads all 64 image rows (route following's
# default); bench/concic2_best_bench.py measured OURS with the thesis's 3 rows.
LAWS: dict[str, dict] = {
    'feedback (thesis)': {},
    'feedback (ours)': {'steering': OURS},
    'feed_forward (positional)': {'camera_law': 'feed_forward',
                                  'feed_forward': FeedForwardParams(form='positional')},
    'feed_forward': {'camera_law': 'feed_forward'},  # the default form, chord; the goals' law
}
FEEDBACK = ('feedback (thesis)', 'feedback (ours)')


def course_layout(course: str, folder: Path) -> Layout:
    """Write the course's tape layout into `folder` and load it (the truck START m along)."""
    segments = COURSES[course][0]
    text = (f'layout: e8_{course}\nvehicle: concic2\nkind: tape\ntapes:\n  - id: main\n'
            f'    start: [0.0, 0.0, 0.0]\n    width: {WIDTH}\n    segments: [{segments}]\n'
            f'start: {{path: main, at: {START}}}\n')
    file = folder / f'e8_{course}.yaml'
    file.write_text(text)
    return load_layout(file)


def truck(lay: Layout, law: str, model: str, speed: float
          ) -> tuple[Harness, WorldCore, RouteCore, CameraLegScript]:
    """Return the lock-step truck on `lay`: world, route following under `law`, executive."""
    # TapeWorld: the world core without its marker sensor, a quarter of a run's time, which
    # a floor without cards leaves dark; nothing in camera mode reads it.
    world = TapeWorld(lay, WorldParams(seed=2, concic2=Concic2Params(model=model)))
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed, **LAWS[law]))
    script = CameraLegScript()
    return Harness(world, [script, route], seed=2), world, route, script


def offsets(world: WorldCore, path) -> tuple[float, float, float, float]:
    """Ground truth now: (window along, |window offset|, worse |caster offset|, axle along), m."""
    s, p = world.vehicle.state, world.p.concic2
    c, n = math.cos(s.heading), math.sin(s.heading)
    along, window, _h = path.project(s.x + p.camera_distance * c, s.y + p.camera_distance * n)
    casters = max(abs(path.project(s.x + k * p.caster_distance * c,
                                   s.y + k * p.caster_distance * n)[1]) for k in (1.0, -1.0))
    return along, abs(float(window)), float(casters), path.project(s.x, s.y)[0]


@dataclass
class Drive:
    """One run of a course: the peaks per curve (m; nan where a span was not reached)."""

    course: str
    law: str
    model: str
    speed: float
    completed: bool = False
    stopped_at: float = math.nan  # m along (the axle) where a run that did not complete ended
    enter: list[tuple[float, float]] = field(default_factory=list)  # (casters, window) peaks
    leave: list[tuple[float, float]] = field(default_factory=list)
    ff_before: list[bool] = field(default_factory=list)  # feed_forward steered as it entered
    ff_share: float = math.nan  # of the frames in the spans, those feed_forward steered
    peak_law: str = '-'  # the law that steered the frame of the largest caster error in a span
    peak_at: float = math.nan  # m of the window along the tape in that frame
    handbacks: list[float] = field(default_factory=list)  # window along where ff stopped steering
    whole: float = math.nan  # largest caster error from the first curve's start on, spans or not
    wall: float = 0.0  # s of wall time the run took

    def peak(self, k: int = 0) -> float:
        """Return the largest caster (k 0) or window (k 1) peak over every span, m."""
        return max((p[k] for p in self.enter + self.leave if not math.isnan(p[k])),
                   default=math.nan)


def spans(course: str) -> list[tuple[str, float, float]]:
    """(entering or leaving, from, to) of each curve in turn: m of the window along the tape."""
    out = []
    for a, b in COURSES[course][1]:
        out += [('enter', a, a + ENTER), ('leave', b - BEFORE, b + AFTER)]
    return out


def drive(course: str, law: str, model: str, speed: float) -> Drive:
    """Drive the course until the axle is FINISH m along the last straight or route stops."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        lay = course_layout(course, Path(folder))
    h, world, route, script = truck(lay, law, model, speed)
    path = lay.paths['main']
    curves = COURSES[course][1]
    finish = curves[-1][1] + FINISH
    limit = 1.5 * (finish - START) / speed + 10.0  # s: the set-off ramp with room to spare
    frames: list[tuple[float, float, float, str]] = []  # window along, window, casters, law
    run = Drive(course, law, model, speed)
    axle = START
    while h.now < limit:
        h.step()
        if world.sample % FRAME:
            continue
        along, window, casters, axle = offsets(world, path)
        frames.append((along, window, casters, route.cam.law.law))
        if script.states and script.states[-1] != 'following':
            break  # no_track: the motor-off stop
        if axle >= finish:
            run.completed = script.states == ['following']
            break
    if not run.completed:
        run.stopped_at = axle
    inside: set[int] = set()
    for kind, lo, hi in spans(course):
        hits = [i for i, f in enumerate(frames) if lo <= f[0] <= hi]
        inside.update(hits)
        peak = (max((frames[i][2] for i in hits), default=math.nan),
                max((frames[i][1] for i in hits), default=math.nan))
        (run.enter if kind == 'enter' else run.leave).append(peak)
        if kind == 'enter':
            # The law of the frames while the window covered the 0.2 m before the curve.
            before = [f[3] for f in frames if lo - 0.2 <= f[0] <= lo]
            run.ff_before.append(bool(before) and set(before) == {'feed_forward'})
    if inside:
        run.ff_share = sum(frames[i][3] == 'feed_forward' for i in inside) / len(inside)
        peak = max(inside, key=lambda i: frames[i][2])
        run.peak_law, run.peak_at = frames[peak][3], frames[peak][0]
    run.whole = max((f[2] for f in frames if f[0] >= curves[0][0]), default=math.nan)
    run.handbacks = [f[0] for e, f in zip(frames, frames[1:], strict=False)
                     if e[3] == 'feed_forward' and f[3] != 'feed_forward']
    run.wall = time.perf_counter() - started
    return run


def steady(law: str, model: str, speed: float = 0.6, seconds: float = 40.0,
           tail: float = 10.0) -> float:
    """Worse caster contact's largest |distance| from tape_1991's circle over the last `tail` s.

    The circle without its road signs and their tapes (concic2_thesis_bench.circle_floor, the
    test's circle_floor), from its layout's start; nan when the route stopped.
    """
    lay = circle_floor()
    h, world, route, script = truck(lay, law, model, speed)
    path = lay.paths['circle']
    worst = 0.0
    while h.now < seconds:
        h.step()
        if world.sample % FRAME == 0 and h.now >= seconds - tail:
            worst = max(worst, offsets(world, path)[2])
    return worst if script.states == ['following'] else math.nan


def grid(lo: float = 0.3, hi: float = 1.2, step: float = 0.05) -> list[float]:
    """Speeds of the top-speed search, m/s."""
    return [round(lo + k * step, 2) for k in range(round((hi - lo) / step) + 1)]


def top_speed(law: str, model: str, known: dict[float, bool]
              ) -> tuple[float, dict[float, bool], str]:
    """Highest speed of grid() that completes the s_bend: (speed, every run's outcome, note).

    A binary search between the highest known completion and the lowest known failure above
    it (`known`: speed -> completed, from the grid of speeds), then the edge's neighbour
    below run too, so that the edge is seen to be one (pass, pass, fail). The note says where
    outcomes are not monotonic in speed. nan: not even the slowest speed completes.
    """
    speeds, tried = grid(), dict(known)

    def ok(v: float) -> bool:
        if v not in tried:
            tried[v] = drive('s_bend', law, model, v).completed
        return tried[v]

    if not ok(speeds[0]):
        return math.nan, tried, 'lost at the slowest speed'
    lo = max(i for i, v in enumerate(speeds) if tried.get(v)
             and all(tried[u] for u in tried if u <= v))
    hi = min((i for i, v in enumerate(speeds) if i > lo and tried.get(v) is False),
             default=None)
    if hi is None:
        if ok(speeds[-1]):
            lo = hi = len(speeds) - 1
        else:
            hi = len(speeds) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if ok(speeds[mid]) else (lo, mid)
    if lo > 0:
        ok(speeds[lo - 1])
    top = speeds[lo]
    odd = sorted(v for v, done in tried.items() if (v > top and done) or (v < top and not done))
    note = 'monotonic where run' if not odd else \
        'not monotonic: ' + ', '.join(f'{v:.2f} {"held" if tried[v] else "lost"}' for v in odd)
    return top, tried, note
