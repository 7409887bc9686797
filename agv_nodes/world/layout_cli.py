"""agv-layout: check layouts before a run (agv_nodes/world/layout_check.py), show their graph.

    agv-layout check FILE [FILE...]
    agv-layout graph FILE [--json]

check: exit 0: the simulated truck reads every marker as driven (a line on stderr for each one
read with little to spare: marginal, with its margin); 1: one line per marker it cannot read
(stderr), each saying how to go on. On a tape floor (the camera truck), a line on stderr for
each bend tighter than the truck can follow and for each crossing a reverse leg meets backing
out of a sign's branch (what it reads there, where no decision and left and right go). graph: the
track graph a VDA 5050 master plans on (agv_nodes/fleet/track_graph.py): its nodes and edges
as a table, or as JSON to load into a master's plant model. Exit 2: a file that is no valid
layout (or, for graph, one without a track graph). FILE may be a layout's name
(config/layouts/<name>.yaml); see docs/architecture.md and docs/vda5050.md.
"""

import argparse
from dataclasses import asdict
import json
import math
import sys

from agv_nodes.world.layout import Layout, LayoutError, layout_path, load_layout
from agv_nodes.world.layout_check import check_layout


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-layout."""
    ap = argparse.ArgumentParser(prog='agv-layout', description=__doc__.splitlines()[0])
    commands = ap.add_subparsers(dest='command', required=True)
    check = commands.add_parser('check', help='can the simulated truck read every marker as it '
                                'drives the route?')
    check.add_argument('files', nargs='+', metavar='FILE', help='layout file or name')
    graph = commands.add_parser('graph', help="the track graph: the markers a master's orders "
                                'name as nodes, the ways between them as edges')
    graph.add_argument('files', nargs=1, metavar='FILE', help='layout file or name')
    graph.add_argument('--json', action='store_true', help='as JSON (nodes, edges, start)')
    args = ap.parse_args(argv)
    layouts = []
    for name in args.files:
        try:
            layouts.append(load_layout(layout_path(name)))
        except LayoutError as exc:
            print(f'agv-layout: {exc}', file=sys.stderr)
            return 2
        except OSError as exc:
            print(f'agv-layout: {name}: {exc.strerror or exc}', file=sys.stderr)
            return 2
        except (AttributeError, KeyError, TypeError) as exc:  # a key of the wrong kind
            print(f'agv-layout: {name}: not a valid layout: {exc}', file=sys.stderr)
            return 2
    if args.command == 'graph':
        return _graph(layouts[0], args.json)
    errors, failed = [], False
    for lay in layouts:
        report = check_layout(lay)
        print(report.table())
        errors += report.errors() + report.warnings() + report.reverse
        failed = failed or bool(report.errors())
    for line in errors:
        print(line, file=sys.stderr)
    return 1 if failed else 0


def _graph(layout: Layout, as_json: bool) -> int:
    """Print the layout's track graph; 2 when it has none."""
    from agv_nodes.fleet.track_graph import track_graph

    try:
        graph = track_graph(layout)
    except LayoutError as exc:
        print(f'agv-layout: {exc}', file=sys.stderr)
        return 2
    if as_json:
        print(json.dumps({'layout': layout.name, 'start': graph.start,
                          'nodes': [asdict(n) for n in graph.nodes.values()],
                          'edges': [asdict(e) for e in graph.edges.values()]}, indent=1))
        return 0
    print(f'layout {layout.name}: {len(graph.nodes)} nodes, {len(graph.edges)} edges (one-way); '
          f'a truck from the start meets {graph.start} first')
    print(f'{"node":6} {"kind":8} {"loc":>3} {"x m":>7} {"y m":>7} {"deg":>6}')
    for n in graph.nodes.values():
        print(f'{n.id:6} {n.kind:8} {n.location:3d} {n.x:7.3f} {n.y:7.3f} '
              f'{math.degrees(n.theta):6.1f}')
    print(f'{"edge":10} {"length m":>8}  how')
    for e in graph.edges.values():
        how = f'SRM {e.srm_angle:+d} deg off the wire' if e.srm_angle else 'along the wire'
        if e.chosen:
            how += ' (a junction: where a task says, srm at N)'
        print(f'{e.id:10} {e.length:8.3f}  {how}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
