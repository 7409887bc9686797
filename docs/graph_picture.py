"""Draw the node and topic graph of one truck: docs/images/node_graph.png.

The nodes come from config/graph.yaml (name, role, realtime) and every arrow from the record
schemas msg_schemas/*.yaml (topic, writer, readers, kind, QoS class, period), so the picture
follows the contract. Only the place of each node on the page is chosen here (PLACES); a node
that is not in PLACES is put on a spare row at the bottom, so a new node still shows.

Run: .venv/bin/python docs/graph_picture.py [--out docs/images/node_graph.png]
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path
import sys

import matplotlib
from matplotlib.lines import Line2D
from matplotlib.patches import FancyBboxPatch
import yaml

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parent.parent

# Where each node sits (x, y): the executive at the top of the 1983 star, the sub-systems
# below it, the hardware side (the simulated world) at the bottom.
PLACES = {
    'communications': (-0.6, 9.0),
    'executive': (7.0, 9.0),
    'load_handling': (14.6, 9.0),
    'navigation': (2.6, 5.4),
    'traction': (7.0, 5.4),
    'route_following': (11.0, 5.4),
    'position_sensor': (0.4, 2.0),
    'world': (8.0, 0.3),
    'recorder': (14.8, -1.7),
}
# The 1983 board (or the role) each node stands for, printed under its name.
BOARDS = {
    'communications': 'Communications board',
    'executive': 'Vehicle Executive board',
    'navigation': 'Position board: navigation',
    'traction': 'Traction board',
    'route_following': 'Route Following / Steering',
    'load_handling': 'Load handling board',
    'position_sensor': 'Position board: sensor',
    'world': 'simulated truck, floor, markers\n(or the hardware drivers)',
    'recorder': 'rosbag2 MCAP of every topic',
}
KIND_COLOURS = {'inter_processor': '#1f5fa8', 'hardware': '#d07000', 'ground_truth': '#7a7a7a'}
KIND_NAMES = {'inter_processor': 'inter-processor record (16 bytes, E2E in bytes 15-16)',
              'hardware': 'hardware-side record (16 bytes)',
              'ground_truth': 'ground truth (simulation only)'}
BOX_W, BOX_H = 2.9, 1.15
# Wide boxes: the executive (the hub of the 1983 star) and the world (most hardware links end
# on it) each aim an arrow from the part of the box facing the other node.
WIDE = {'executive': 5.6, 'world': 10.0}


def load_graph(path: Path) -> list[dict]:
    """Load the nodes of config/graph.yaml."""
    return yaml.safe_load(path.read_text())['nodes']


def load_records(folder: Path) -> list[dict]:
    """Every record schema (topic, writer, readers, kind, qos, period_ms)."""
    records = []
    for path in sorted(folder.glob('*.yaml')):
        doc = yaml.safe_load(path.read_text())
        doc.setdefault('qos', 'record')
        records.append(doc)
    return records


def places(nodes: list[dict]) -> dict[str, tuple[float, float]]:
    """PLACES, plus a spare row for nodes it does not know."""
    out = {}
    spare = 0
    for node in nodes:
        name = node['name']
        if name in PLACES:
            out[name] = PLACES[name]
        else:
            out[name] = (1.2 + 3.4 * spare, -2.0)
            spare += 1
    return out


def box_width(name: str) -> float:
    """Width of a node's box."""
    return WIDE.get(name, BOX_W)


def exit_point(name: str, pos: dict, start: tuple[float, float],
               towards: tuple[float, float]) -> tuple[float, float]:
    """Where the ray from `start` (inside `name`'s box) towards `towards` leaves the box."""
    cx, cy = pos[name]
    half_w, half_h = box_width(name) / 2, BOX_H / 2
    (x, y), (tx, ty) = start, towards
    dx, dy = tx - x, ty - y
    steps = []
    if dx:
        steps.append(((cx + half_w if dx > 0 else cx - half_w) - x) / dx)
    if dy:
        steps.append(((cy + half_h if dy > 0 else cy - half_h) - y) / dy)
    s = min(steps) if steps else 0.0
    return x + dx * s, y + dy * s


def anchor(name: str, pos: dict, other: str) -> tuple[float, float]:
    """Return the point a box aims from.

    A wide box aims from the part of it above or below the other node (its own centre for a
    node beside it).
    """
    x, y = pos[name]
    if name in WIDE and abs(pos[other][1] - y) > BOX_H:
        half = WIDE[name] / 2 - 0.4
        x = min(max(pos[other][0], x - half), x + half)
    return x, y


def bezier(p0: tuple[float, float], p2: tuple[float, float], rad: float,
           t: float) -> tuple[float, float]:
    """Return a point of matplotlib's arc3 curve from p0 to p2 (a quadratic Bezier)."""
    (x0, y0), (x2, y2) = p0, p2
    cx = (x0 + x2) / 2 + rad * (y2 - y0)
    cy = (y0 + y2) / 2 - rad * (x2 - x0)
    u = 1 - t
    return u * u * x0 + 2 * u * t * cx + t * t * x2, u * u * y0 + 2 * u * t * cy + t * t * y2


def label(record: dict) -> str:
    """Return a topic and its rate (Hz when faster than 50 Hz, else its period)."""
    period = record['period_ms']
    rate = f'{1000 / period:.0f} Hz' if period < 20 else f'{period:g} ms'
    return f'{record["topic"]}  ({rate})'


def draw(out: Path) -> None:
    """Draw the picture into `out`."""
    nodes = load_graph(REPO / 'config' / 'graph.yaml')
    records = load_records(REPO / 'msg_schemas')
    pos = places(nodes)

    # One arrow per (writer, reader) pair; its label lists every topic on it.
    links: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for rec in records:
        for reader in rec['readers']:
            if rec['writer'] in pos and reader in pos:
                links[(rec['writer'], reader)].append(rec)

    fig, ax = plt.subplots(figsize=(16, 12.4))
    ax.set_aspect('equal')
    ax.axis('off')
    ys = [y for _x, y in pos.values()]
    ax.set_xlim(-2.4, 16.4)
    ax.set_ylim(min(ys) - 2.7, max(ys) + 1.0)

    for (writer, reader), recs in sorted(links.items()):
        back = (reader, writer) in links
        a = anchor(writer, pos, reader)
        b = anchor(reader, pos, writer)
        start = exit_point(writer, pos, a, b)
        end = exit_point(reader, pos, b, a)
        # Two arrows between the same pair bow apart (arc3 bends each to its own side), and
        # each is labelled nearer its writer, so the two labels do not meet.
        rad = 0.2 if back else 0.0
        colour = KIND_COLOURS[sorted(r['kind'] for r in recs)[0]]
        stream = all(r['qos'] == 'stream' for r in recs)
        ax.annotate('', xy=end, xytext=start,
                    arrowprops=dict(arrowstyle='-|>', color=colour, lw=1.6,
                                    mutation_scale=16, shrinkA=2, shrinkB=2,
                                    linestyle=(0, (5, 3)) if stream else '-',
                                    connectionstyle=f'arc3,rad={rad}'))
        mx, my = bezier(start, end, rad, 0.33 if back else 0.5)
        if not back and abs(end[1] - start[1]) < 0.3 * abs(end[0] - start[0]):
            my += 0.8  # a short level arrow: its label above it and the boxes
        text = '\n'.join(label(r) for r in sorted(recs, key=lambda r: r['topic']))
        ax.text(mx, my, text, ha='center', va='center', fontsize=8.5, color=colour,
                family='monospace', zorder=5,
                bbox=dict(boxstyle='round,pad=0.2', fc='white', ec='none', alpha=0.9))

    for node in nodes:
        name = node['name']
        x, y = pos[name]
        width = box_width(name)
        role = node.get('role', 'node')
        realtime = bool(node.get('realtime'))
        face = {'world': '#fff1dc', 'recorder': '#eeeeee'}.get(role, '#e3eefb')
        ax.add_patch(FancyBboxPatch((x - width / 2, y - BOX_H / 2), width, BOX_H,
                                    boxstyle='round,pad=0.05,rounding_size=0.15', fc=face,
                                    ec='#222222' if realtime else '#777777',
                                    lw=2.6 if realtime else 1.0, zorder=3))
        ax.text(x, y + 0.2, name, ha='center', va='center', fontsize=12, weight='bold',
                zorder=4)
        ax.text(x, y - 0.25, BOARDS.get(name, role), ha='center', va='center', fontsize=8,
                color='#333333', zorder=4)

    legend = [Line2D([0], [0], color=c, lw=2, label=KIND_NAMES[k])
              for k, c in KIND_COLOURS.items()]
    legend += [Line2D([0], [0], color='k', lw=1.6, label='record QoS: reliable, '
                      'transient-local writer; reliable, volatile readers'),
               Line2D([0], [0], color='k', lw=1.6, ls=(0, (5, 3)),
                      label='stream QoS: reliable writer; best-effort readers'),
               Line2D([0], [0], color='#222222', lw=0, marker='s', markersize=11,
                      markerfacecolor='white', markeredgewidth=2.6,
                      label='realtime: SCHED_FIFO with agv-launch --realtime N')]
    ax.legend(handles=legend, loc='lower left', fontsize=9, frameon=True)
    ax.set_title('One truck: nodes (config/graph.yaml) and record topics (msg_schemas/*.yaml)'
                 '\nNot drawn: /clock, sim/progress/<node>, graph/links, /diagnostics, '
                 'comms/task, comms/report, hw/camera/*, hw/radio_stop, world/pose|route|'
                 'markers', fontsize=12)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    print(f'wrote {out}')


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', type=Path, default=REPO / 'docs' / 'images' / 'node_graph.png')
    draw(ap.parse_args().out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
