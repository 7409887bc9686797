"""The identified track against the true tape, for the camera report (Rajagopalan 1991, 5.4).

route_following publishes the track it identifies (feed-forward and dead-reckoning legs) as
route/identified_track, a nav_msgs/Path in its odometry frame; read_bag collects every message.
Here they are placed in the world and measured against the layout's tapes.
"""

import math
from typing import Any

import numpy as np

from agv_nodes.world.layout import Layout

# route_following's picture of the identified track, in its odometry frame.
IDENTIFIED_TRACK = 'route/identified_track'


def identified_track_messages(data: dict[str, Any]) -> list[tuple[float, np.ndarray]]:
    """route/identified_track's messages, each (t, (n, 2) points) placed in the world.

    Their frame, `odom`, is the pose route following integrated from wheel odometry since it
    started, the truck at rest: its origin and x axis are the axle centre and heading of the
    bag's first world pose. Empty without the topic (any namespace) or without a pose.
    """
    topics = [topic for topic in data.get('paths', {})
              if topic == '/' + IDENTIFIED_TRACK or topic.endswith('/' + IDENTIFIED_TRACK)]
    if not topics or not data['pose']:
        return []
    _t, x0, y0, h0 = data['pose'][0]
    turn = np.array([[math.cos(h0), -math.sin(h0)], [math.sin(h0), math.cos(h0)]])
    return [(t, np.asarray(points, dtype=float).reshape(-1, 2) @ turn.T + (x0, y0))
            for topic in topics for t, points in data['paths'][topic]]


def tape_distance(layout: Layout, points: np.ndarray) -> np.ndarray:
    """M from each point to the nearest tape centreline of `layout` (sign patches left out).

    The distance to the nearest point of the centreline: project()'s |lateral| beside a tape,
    but to the end beyond one, where project()'s lateral stays square to the last segment and
    would put a point in line with a tape's end on it. Taken on the two segments either side
    of each tape's nearest sample point (project() tries every segment, too slow for a run's
    10^5 points): the same unless a tape comes back within a sample step of itself. The
    patches lie along their tapes.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    best = np.full(len(points), np.inf)
    for pid, path in layout.paths.items():
        if 'patch' in pid:
            continue
        a = path.points
        if len(a) < 2:
            best = np.minimum(best, np.hypot(*(points - a[0]).T))
            continue
        d = np.diff(a, axis=0)
        dd = np.maximum(np.einsum('ij,ij->i', d, d), 1e-18)
        sq = np.einsum('ij,ij->i', a, a)
        for k in range(0, len(points), 4096):  # chunks of points x samples
            p = points[k:k + 4096]
            near = np.argmin(sq[None, :] - 2.0 * p @ a.T, axis=1)
            either = ((near - 1) % len(d), near % len(d)) if path.closed else \
                (np.maximum(near - 1, 0), np.minimum(near, len(d) - 1))
            for j in either:
                rel = p - a[j]
                t = np.clip(np.einsum('ij,ij->i', rel, d[j]) / dd[j], 0.0, 1.0)
                best[k:k + 4096] = np.minimum(best[k:k + 4096],
                                              np.hypot(*(rel - t[:, None] * d[j]).T))
    return best


def identified_track_numbers(data: dict[str, Any], layout: Layout) -> dict[str, Any] | None:
    """Messages of route/identified_track and their points' distance from the tape (mm).

    Over every point of every message (a window's points counted in each message that holds
    them). None without the topic.
    """
    messages = identified_track_messages(data)
    if not messages:
        return None
    points = np.concatenate([p for _t, p in messages])
    mm = 1000.0 * tape_distance(layout, points) if len(points) else np.zeros(0)
    return {'messages': len(messages), 'points': int(len(points)),
            'mean_mm': float(mm.mean()) if len(mm) else None,
            'max_mm': float(mm.max()) if len(mm) else None}
