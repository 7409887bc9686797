"""What the layout check found: each marker's worst pass, its grade, and the report's lines.

agv_nodes.world.layout_check drives the layout and fills these in; the CLI (agv-layout check),
the world node and the lock-step harness read the lines.
"""

from dataclasses import dataclass, field
import math

from agv_nodes.world.layout import Layout, Marker
from agv_nodes.world.marker_sensor import READ_ANGLE, READ_STANDOFF
from agv_nodes.world.readability import Pose, Readability


@dataclass
class Passage:
    """A marker as the truck passes it: the pass of all drives furthest from the working range."""

    marker: Marker
    standoff: float = math.nan  # m, lens to card along the optical axis, as it meets the centre
    angle: float = math.nan  # degrees, the card's normal off the axis (+ = card turned left)
    drive: str = ''
    closest: float = math.inf  # m, the lens's closest approach to the card centre (any drive)
    poses: list[Pose] = field(default_factory=list, repr=False)  # the lens over that pass
    read: Readability | None = None  # the simulated sensor's verdict on that pass

    @property
    def passed(self) -> bool:
        """Return True when the optical axis crossed the card centre on some drive."""
        return not math.isnan(self.standoff)

    @property
    def score(self) -> float:
        """Return how far out it is as a fraction of the range's half-width (> 1: outside)."""
        if not self.passed:
            return math.inf
        lo, hi = READ_STANDOFF
        return max(abs(self.standoff - (lo + hi) / 2.0) / ((hi - lo) / 2.0),
                   abs(self.angle) / READ_ANGLE)

    @property
    def in_range(self) -> bool:
        """Return True when the pass lies in the thesis's working range (Baker 1983, 7.1)."""
        lo, hi = READ_STANDOFF
        return self.passed and lo <= self.standoff <= hi and abs(self.angle) <= READ_ANGLE

    @property
    def grade(self) -> str:
        """Return 'unreadable', 'marginal' or '' (read with room to spare, or not judged)."""
        if not self.passed or (self.read is not None and not self.read.readable):
            return 'unreadable'
        return 'marginal' if self.read is not None and self.read.marginal else ''

    def problem(self) -> str:
        """Return why the card is refused or marginal, with its margin ('' when neither)."""
        if not self.passed:
            return (f'never crossed by the optical axis as driven (closest {self.closest:.3f} m; '
                    'seen edge-on, off the route or beyond the view)')
        if not self.grade:
            return ''
        what = ('the simulated sensor does not read it' if self.grade == 'unreadable' else
                'read, but near the edge')
        return (f'{what} as driven (standoff {self.standoff:.3f} m, angle {self.angle:+.1f} '
                f'deg): {self.read.margin() if self.read else ""}')


HOW_TO_GO_ON = ("to run anyway: -p world:layout_check:=warn (harness: layout_check='warn'); "
                'or move or turn the card as the margin says')


@dataclass
class Report:
    """Every marker of a layout as driven."""

    layout: Layout
    passages: list[Passage]
    note: str = ''
    signs: list[str] = field(default_factory=list)  # tape floors: each sign and its branches
    bends: list[str] = field(default_factory=list)  # tape bends tighter than the truck follows
    reverse: list[str] = field(default_factory=list)  # crossings met backing out of a branch

    def errors(self) -> list[str]:
        """Return one line per marker the simulated truck cannot read, saying how to go on."""
        return [f'{self._line(p)}; {HOW_TO_GO_ON}' for p in self.passages
                if p.grade == 'unreadable']

    def warnings(self) -> list[str]:
        """Return one line per marker read with little to spare (marginal), with its margin.

        And one per tape bend tighter than the camera truck can follow.
        """
        return [self._line(p) for p in self.passages if p.grade == 'marginal'] + self.bends

    def _line(self, p: Passage) -> str:
        return (f'layout {self.layout.file}: {p.grade} marker {p.marker.name!r} at '
                f'({p.marker.centre[0]:.2f}, {p.marker.centre[1]:.2f}): {p.problem()}'
                f'{f" ({p.drive})" if p.drive else ""}')

    def table(self) -> str:
        """Return the per-marker table: marker, standoff m, angle deg, thesis range, reads."""
        lay = self.layout
        lines = [f'layout {lay.file} ({lay.kind}, {lay.vehicle}): {len(self.passages)} markers'
                 f'{f"; {self.note}" if self.note else ""}']
        if self.passages:
            lines.append(f'{"marker":8} {"path":>5} {"at m":>7} {"standoff m":>10} '
                         f'{"angle deg":>9} {"in range":>8} {"reads":>10}  worst pass')
        for p in self.passages:
            m = p.marker
            standoff = f'{p.standoff:.3f}' if p.passed else '-'
            angle = f'{p.angle:+.1f}' if p.passed else '-'
            reads = p.grade or ('yes' if p.read is not None else '-')
            lines.append(f'{m.name:8} {m.path:>5} {m.at:7.3f} {standoff:>10} {angle:>9} '
                         f'{"yes" if p.in_range else "no":>8} {reads:>10}  {p.drive}')
        if self.signs:
            lines.append(f'{len(self.signs)} road signs (Rajagopalan 1991, 4.3):')
            lines += [f'  {line}' for line in self.signs]
        if self.reverse:
            lines.append(f'{len(self.reverse)} crossings met by a reverse leg backing out of a '
                         'branch (a task script decides them; docs/tasks.md)')
        return '\n'.join(lines)
