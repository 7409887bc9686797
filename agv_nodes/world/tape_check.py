"""Layout check of a tape floor: bends the camera truck cannot follow, crossings met in reverse.

The CONCIC-II's window is L_c (`turning.camera_ahead`, 0.64 m) ahead of the axle centre
(Rajagopalan 1991, Table 6.1). Following a circle of radius R with the window centred on the
tape, axle and window run on circles about one centre, the axle's of radius r_a, and
R^2 = r_a^2 + L_c^2; the tape then crosses the window at eps_theta = asin(L_c / R) to the
direction of travel. Two limits follow from that geometry:

- the caster angle: the axle's radius is L_ae / tan(theta_s) (Eq. 5.10-5.11), at least that at
  `steering.max_angle`, so R >= sqrt(L_c^2 + (L_ae / tan(max_angle))^2) (0.67 m);
- the road-sign test (4.3): a row across the window cuts a tape at eps_theta over its width /
  cos(eps_theta), and a run `image.wide_factor` times the normal width reads as a road sign, so
  a bend with cos(eps_theta) < 1 / wide_factor reads as a sign on plain tape (0.95 m).

The larger is the smallest followable radius; a tighter bend is warned of. Measured in lock step
(test/test_tape_layout_check.py, 200 deg bends at the default cruise): at 0.6 m the truck loses
the tape, at 0.85 m it reads a road sign on plain tape, at 1.05 m neither (docs/tasks.md).

Reverse legs: a tape task's `then reverse` backs out along the way it came, and a forward leg
that took a sign's turning branch meets that sign's crossing again from the branch, the rear
window reading the sign's tape across its way. For every turning branch of every sign (every
reverse leg a layout allows back to a crossing) the check says what the window reads there,
where no decision goes (straight across, onto the tape beyond or off the tape, ending the
leg there) and where left and right of travel lead; the task's script may decide it (its
junction numbers go on from the forward leg's, docs/tasks.md).
"""

import math

import numpy as np

from agv_nodes.route_following.camera_guidance import sign_name
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.layout import Layout
from agv_nodes.world.tape_layout import ON_JUNCTION, SQUARE_DEG, Path2D

LEADS = 0.1  # m of tape from a crossing that the window sees as a way on


def smallest_radius(route: RouteParams | None = None) -> tuple[float, str]:
    """Return the smallest radius (m) the window geometry can follow, and what limits it."""
    p = route or RouteParams()
    ahead, s = p.turning.camera_ahead, p.steering
    lae = s.caster_distance + s.caster_trail * (1.0 - math.cos(s.max_angle))
    caster = math.hypot(ahead, lae / math.tan(s.max_angle))
    wide = ahead / math.sqrt(1.0 - 1.0 / p.image.wide_factor ** 2)
    if wide >= caster:
        angle = math.degrees(math.asin(ahead / wide))
        return wide, (f'the tape would cross the window at {angle:.0f} deg and read '
                      f'{p.image.wide_factor} times its width: a road sign')
    return caster, f'the caster angle would pass max_angle {math.degrees(s.max_angle):.0f} deg'


def tight_bends(layout: Layout, route: RouteParams | None = None) -> list[str]:
    """Return one warning per bend of a tape tighter than `smallest_radius`."""
    limit, why = smallest_radius(route)
    p = route or RouteParams()
    lines = []
    for tape in layout.paths.values():
        if tape.width == 0.0:
            continue
        turn = _wrap(tape.headings[1:] - tape.headings[:-1])
        step = tape.s[1:] - tape.s[:-1]
        tight = (abs(turn) > 1e-9) & (step > 0) & (step < abs(turn) * limit)
        k = 0
        while k < len(tight):
            if not tight[k]:
                k += 1
                continue
            j = k
            while j + 1 < len(tight) and tight[j + 1]:
                j += 1
            radius = float(min(step[k:j + 1] / abs(turn[k:j + 1])))
            x, y, _h = tape.pose_at(float(tape.s[k]))
            lines.append(f'layout {layout.file}: tape {tape.id!r}: a bend of R {radius:.2f} m '
                         f'from {tape.s[k]:.2f} to {tape.s[j + 1]:.2f} m along ({x:.2f}, '
                         f'{y:.2f}) is tighter than the {limit:.2f} m the camera truck can '
                         f'follow with its window {p.turning.camera_ahead} m ahead of the axle '
                         f'({why}); widen it')
            k = j + 1
    return lines


def _wrap(a: np.ndarray) -> np.ndarray:
    """Return angles (rad) wrapped into -pi..pi."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def reverse_crossings(layout: Layout) -> list[str]:
    """Return one line per crossing a reverse leg meets backing out of a sign's turning branch."""
    tapes = {i: p for i, p in layout.paths.items() if p.width > 0 and '_patch' not in i}
    lines = []
    for n, sign in enumerate(layout.signs):
        jx, jy, jh = layout.paths[sign['path']].pose_at(sign['at'])
        where = f'({round(jx, 2) + 0.0:.2f}, {round(jy, 2) + 0.0:.2f})'
        for side, tid in sign['tapes'].items():
            branch = math.pi / 2 if side == 'left' else -math.pi / 2
            travel = jh + branch + math.pi  # backing down the branch toward the crossing
            ways = {way: _leads(tapes, (jx, jy), travel + turn)
                    for way, turn in (('left', math.pi / 2), ('right', -math.pi / 2),
                                      ('straight', 0.0))}
            read = sign_name(*(int(bool(ways[w])) for w in ('left', 'right', 'straight')))
            across = (f'straight across onto {ways["straight"]}' if ways['straight'] else
                      'straight across and off the tape: the leg ends there')
            turns = '; '.join(f'{way} of travel: along {ways[way]}' for way in ('left', 'right')
                              if ways[way])
            lines.append(f'layout {layout.file}: a reverse leg backing out of sign {n + 1} '
                         f'({sign["type"]} on {sign["path"]})\'s {side} branch {tid} meets the '
                         f'crossing at {where} read as {read or "nothing"}: no '
                         f'decision goes {across}' + (f'; {turns}' if turns else ''))
    return lines


def _leads(tapes: dict[str, Path2D], at: tuple[float, float], heading: float) -> str:
    """Return the tape that runs on from `at` along `heading` (LEADS m at least), or ''."""
    square = math.cos(math.radians(SQUARE_DEG))
    for tid, tape in tapes.items():
        s, _lateral, tangent = tape.project(*at)
        if math.dist(at, tape.pose_at(s)[:2]) > ON_JUNCTION:
            continue
        cos = math.cos(tangent - heading)
        if cos > square and (tape.closed or tape.length - s > LEADS):
            return f'{tid} toward its end' if not tape.closed else f'{tid} (its direction)'
        if cos < -square and (tape.closed or s > LEADS):
            return f'{tid} toward its start' if not tape.closed else f'{tid} (against it)'
    return ''
