"""agv-demo: the main job of the README.

The closed-loop demonstration (the whole graph, one process per node, the demonstration
programme of thesis 7.2 in the simulated room, recorded to a bag) is built issue by issue. Until
it exists this command says so and shows what does exist: the record layer, by walking the
status/link records of the task "stop at location 2, first stop marker" (spec 4) through the
codec exactly as navigation will publish them.
"""

from __future__ import annotations

import sys

from agv_nodes.records import codec

SPEC4_STEPS = [
    ('power-up', dict(), dict()),
    ('executive sends INFO = {02, 00}', dict(slow=0, lost=0, last_marker=0),
     dict(executive_priority=1)),
    ('location 1 passed', dict(slow=0, lost=0, last_marker=1), dict(executive_priority=1)),
    ('location 2 seen', dict(at_location=1, slow=1, lost=0, last_marker=2), dict(speed=20)),
    ('centre stop view seen', dict(at_location=1, slow=1, lost=1, last_marker=2), dict()),
]


def main(argv: list[str] | None = None) -> int:
    """Print the interim demonstration."""
    c = codec()
    print('agv-demo: the closed-loop demonstration is not built yet (issues 3-8).')
    print('What exists: the 16-byte record layer. The spec 4 task "stop at location 2, first')
    print('stop marker", as navigation_status / traction_link records (e2e protected):\n')
    print(f'{"step":34s} {"navigation_status":34s} {"traction_link":34s}')
    for counter, (what, status, link) in enumerate(SPEC4_STEPS):
        s = c.encode('navigation_status', status, counter=counter).hex().upper()
        t = c.encode('traction_link', link, counter=counter).hex().upper()
        print(f'{what:34s} {s:34s} {t:34s}')
    print('\nByte 1 of navigation_status: 0AH, 00H, 00H, 03H, 0BH; traction_link: 00H, 40H, '
          '40H, 14H, 00H (thesis fig 6.2, spec 1.7, 1.9).')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
