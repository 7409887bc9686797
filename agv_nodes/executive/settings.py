"""Executive settings: the classes its parameters.yaml declares the parameters of."""

from collections.abc import Iterable
from typing import Any

from agv_nodes.settings import settings_class


def parse_srm_map(entries: Iterable[str]) -> dict[int, int]:
    """('1:15', '3:15') -> {1: 15, 3: 15} (deg, + = left); ValueError: entry not 0-31:-45..45."""
    out = {}
    for entry in entries:
        location, _, angle = entry.partition(':')
        try:
            loc, ang = int(location), int(angle)
        except ValueError:
            raise ValueError(entry) from None
        if not (0 <= loc <= 31 and -45 <= ang <= 45):
            raise ValueError(entry)
        out[loc] = ang
    return out


@settings_class
class ExecutiveParams:
    """Tasks into sub-system commands, the route map, and the supervision of the truck."""

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks `build` needs beyond each field's own: the route map's entries."""
        try:
            parse_srm_map(self.srm_map)
        except ValueError as exc:
            return [('srm_map', list(self.srm_map), f'entry {exc.args[0]!r} is not '
                     'location:angle with location 0-31 and angle -45..45')]
        return []
