"""agv-layout: check layouts before a run (agv_nodes/world/layout_check.py).

    agv-layout check FILE [FILE...]

Exit 0: every marker readable; 1: one line per marker that is not (stderr); 2: a file that is no
valid layout. FILE may be a layout's name (config/layouts/<name>.yaml); see docs/architecture.md.
"""

import argparse
import sys

from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.layout_check import check_layout


def main(argv: list[str] | None = None) -> int:
    """Entry point of agv-layout."""
    ap = argparse.ArgumentParser(prog='agv-layout', description=__doc__.splitlines()[0])
    commands = ap.add_subparsers(dest='command', required=True)
    check = commands.add_parser('check', help='can the marker sensor read every marker as the '
                                'truck drives the route?')
    check.add_argument('files', nargs='+', metavar='FILE', help='layout file or name')
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
    errors = []
    for lay in layouts:
        report = check_layout(lay)
        print(report.table())
        errors += report.errors()
    for line in errors:
        print(line, file=sys.stderr)
    return 1 if errors else 0


if __name__ == '__main__':
    sys.exit(main())
