"""Draw what a Foxglove client receives from a live run: docs/images/live_scene.png.

Runs `agv-demo --foxglove PORT` (the real node graph over DDS, with its live view),
connects the plain protocol client of the tests (test/foxglove_client.py: the published
Foxglove WebSocket protocol, nothing of foxglove-sdk), subscribes to `/scene` and `/tf`, and
draws, seen from above, the scene entities as they arrive (the wires, the marker cards, the
stations, the truck's body in `base_link`) and the truck's path as `map -> odom -> base_link`
placed it. Foxglove's own 3D panel draws the same messages in perspective; nothing here is
computed from the simulation itself.

Run: .venv/bin/python docs/live_scene_picture.py [--out docs/images/live_scene.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from typing import Any

import matplotlib
from matplotlib.patches import Polygon
from websockets.exceptions import ConnectionClosed

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / 'test'))
from foxglove_client import MESSAGE_DATA, FoxgloveClient  # noqa: E402

Pose2 = tuple[float, float, float]


def free_port() -> int:
    """Return a TCP port nobody listens on now."""
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


def planar(transform: dict[str, Any]) -> Pose2:
    """Return (x, y, heading) of a decoded FrameTransform or Pose."""
    t = transform.get('translation', transform.get('position', {}))
    q = transform.get('rotation', transform.get('orientation', {}))
    heading = 2.0 * math.atan2(q.get('z', 0.0), q.get('w', 1.0))
    return t.get('x', 0.0), t.get('y', 0.0), heading


def compose(a: Pose2, b: Pose2) -> Pose2:
    """Return b, given in frame a, in a's parent."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]


def connect(port: int, timeout: float) -> FoxgloveClient:
    """Connect once the live view listens (the graph takes a few seconds to start)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return FoxgloveClient(f'ws://127.0.0.1:{port}')
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.5)


def watch(client: FoxgloveClient, seconds: float) -> tuple[dict[str, Any], list[Pose2],
                                                             dict[str, Pose2]]:
    """Return the scene entities by id, the truck's path in map and the last frames in map."""
    topics = ['/scene', '/tf']
    client.wait_for_channels(topics, timeout=60)
    client.subscribe(topics)
    entities: dict[str, Any] = {}
    links: dict[str, tuple[str, Pose2]] = {}  # child -> (parent, pose in parent)
    path: list[Pose2] = []
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            frame = client._next(deadline + 1.0, 'frames')
        except ConnectionClosed:  # the demonstration ended first
            break
        if frame is None or frame[0] != MESSAGE_DATA:
            continue
        sub_id, _log_time = struct.unpack_from('<IQ', frame, 1)
        channel = client._subs[sub_id]
        msg = client.decode(channel, frame[13:])
        if channel['topic'] == '/scene':
            for e in msg.get('entities', []):
                entities[e['id']] = e
            continue
        for t in msg.get('transforms', []):
            links[t['child_frame_id']] = (t['parent_frame_id'], planar(t))
        if 'base_link' in links and 'odom' in links:
            path.append(compose(links['odom'][1], links['base_link'][1]))
    in_map = {}
    for child in links:
        pose, name, hops = (0.0, 0.0, 0.0), child, 0
        while name in links and hops < 8:
            parent, rel = links[name]
            pose, name, hops = compose(rel, pose), parent, hops + 1
        if name == 'map':
            in_map[child] = pose
    return entities, path, in_map


def rgba(color: dict[str, float]) -> tuple[float, float, float, float]:
    """Return a matplotlib colour of a Foxglove Color."""
    return (color.get('r', 0.0), color.get('g', 0.0), color.get('b', 0.0), color.get('a', 1.0))


def rectangle(centre: Pose2, length: float, width: float) -> list[tuple[float, float]]:
    """Return the corners of a length x width rectangle at `centre`."""
    return [compose(centre, (dx * length / 2.0, dy * width / 2.0, 0.0))[:2]
            for dx, dy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]


def draw(entities: dict[str, Any], path: list[Pose2], frames: dict[str, Pose2],
         out: Path) -> None:
    """Draw the scene from above."""
    fig, ax = plt.subplots(figsize=(10, 6.5), dpi=110)
    for e in entities.values():
        origin = (0.0, 0.0, 0.0) if e['frame_id'] == 'map' else frames.get(e['frame_id'])
        if origin is None:
            continue
        for line in e.get('lines', []):
            pts = [compose(origin, (p.get('x', 0.0), p.get('y', 0.0), 0.0))[:2]
                   for p in line.get('points', [])]
            if pts:
                ax.plot(*zip(*pts, strict=True), color=rgba(line['color']), zorder=1,
                        linewidth=max(1.0, 40 * line.get('thickness', 0.01)))
        for cube in e.get('cubes', []):
            size = cube['size']
            corners = rectangle(compose(origin, planar(cube['pose'])), size.get('x', 0.0),
                                max(size.get('y', 0.0), 0.03))
            ax.add_patch(Polygon(corners, closed=True, color=rgba(cube['color']), zorder=3))
        for text in e.get('texts', []):
            x, y, _h = compose(origin, planar(text['pose']))
            ax.annotate(text['text'], (x, y), fontsize=7, color='dimgray', zorder=4,
                        xytext=(3, 3), textcoords='offset points')
    if path:
        ax.plot([p[0] for p in path], [p[1] for p in path], color='tab:blue', linewidth=1.2,
                linestyle=':', zorder=2, label='base_link in map, from /tf')
        ax.legend(loc='upper right', fontsize=8)
    ax.set_aspect('equal')
    ax.set_xlabel('x in map (m)')
    ax.set_ylabel('y in map (m)')
    ax.set_title('What a Foxglove client receives from agv-demo --foxglove: /scene and /tf, '
                 'seen from above', fontsize=10)
    ax.grid(True, linewidth=0.3)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)


def main() -> None:
    """Run the demonstration with its live view and draw what a client receives."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', type=Path, default=REPO / 'docs' / 'images' / 'live_scene.png')
    ap.add_argument('--seconds', type=float, default=150.0,
                    help='how long to watch at most (real s; the run may end first)')
    args = ap.parse_args()
    port = free_port()
    with tempfile.TemporaryDirectory() as run_dir:
        demo = subprocess.Popen(
            [str(REPO / '.venv' / 'bin' / 'agv-demo'), '--foxglove', str(port),
             '--out', run_dir, '--no-report'], stdout=subprocess.DEVNULL,
            stderr=subprocess.STDOUT)
        client = None
        try:
            client = connect(port, timeout=180.0)
            entities, path, frames = watch(client, args.seconds)
        finally:
            if client is not None:
                client.close()
            demo.send_signal(signal.SIGINT)
            try:
                demo.wait(timeout=60)
            except subprocess.TimeoutExpired:
                demo.kill()
    draw(entities, path, frames, args.out)
    print(f'{args.out}: {len(entities)} scene entities, {len(path)} poses of the truck')


if __name__ == '__main__':
    main()
