"""Write docs/parameters.md: every node parameter, from the package's parameters.yaml files.

The tables are made from the declarations the nodes themselves declare their parameters from
(agv_nodes/**/parameters.yaml), so they cannot drift from the code; test/test_foundation.py
checks that the committed page is the one this script makes.

Run: .venv/bin/python docs/parameter_table.py [--out docs/parameters.md]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parent.parent

HEADER = """# Parameters

Every parameter of every node: its default, its limits and what it means. Made by
`docs/parameter_table.py` from the `parameters.yaml` beside each node's code, the one place
they are declared; `ros2 param describe <node> <name>` shows the same. Read-only parameters
are read at start-up; the others may change while the node runs. What the demonstration changes
is in `config/agv_demo.yaml`, with the reason for each value.
"""


def _limits(entry: dict) -> str:
    words = []
    if 'choices' in entry:
        words.append(', '.join(f'`{c}`' for c in entry['choices']))
    if 'range' in entry:
        words.append('{} .. {}'.format(*entry['range']))
    if 'length' in entry:
        words.append(f'{entry["length"]} values (or none)')
    if not entry.get('read_only', True):
        words.append('may change at run time')
    return '; '.join(words)


def page() -> str:
    """Return the whole page."""
    out = [HEADER]
    files = {path: yaml.safe_load(path.read_text())
             for path in sorted((REPO / 'agv_nodes').rglob('parameters.yaml'))}
    # A group may be declared in one file and nested in another's settings (route following's
    # identification and feed_forward are track_geometry's): the prefixes come from them all.
    prefixes = {group: f'{name}.' for sections in files.values() for section in sections.values()
                for name, group in section.items() if isinstance(group, str)}
    for path, sections in files.items():
        out.append(f'\n## `{path.relative_to(REPO)}`')
        for cls, section in sections.items():
            prefix = prefixes.get(cls, '')
            out.append(f'\n### {cls}\n\n| name | default | limits | meaning |\n|---|---|---|---|')
            for name, entry in section.items():
                if isinstance(entry, str):
                    out.append(f'| `{name}.*` | | | the group {entry} |')
                    continue
                default = yaml.safe_dump(entry['default'], default_flow_style=True,
                                         width=1000).strip().removesuffix('...').strip()
                text = ' '.join(str(entry['description']).split()).replace('|', '\\|')
                out.append(f'| `{prefix}{name}` | `{default}` | {_limits(entry)} | {text} |')
    return '\n'.join(out) + '\n'


def main() -> None:
    """Write the page."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', type=Path, default=REPO / 'docs' / 'parameters.md')
    args = ap.parse_args()
    args.out.write_text(page())
    print(f'wrote {args.out}')


if __name__ == '__main__':
    main()
