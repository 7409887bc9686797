"""Sequence decoding of the navigating table: each detector column reads a passing card in time.

The thesis needs one snapshot with all eight detectors outside their invalid band (Baker 1983,
5.2.3); off focus, with the along-track skew (7.1.3: +-1 sample) and at speed (a 20 mm element
lasts 6.8 snapshots at 1 m/s) that is rare: over 280-320 mm standoff and +-10 mm height the thesis
rule missed 974 of 10,020 passes at 1 m/s (bench/recognition_bench.py).

Yet every column sees every element of its row go by. Each navigating card (location markers, 4.3,
fig 4.6; the stop centre view, fig 4.4) is four elements long, white in its first and last, so each
column sees one white-bounded window four elements long, and read at the middle of each quarter its
two detectors give the whole CODE at their own time (skew cannot split them). A card is recognised
when `agree` columns read the same template, no clean column read another, and every window is as
long as four elements at the speed the columns' start times (20 mm apart) give: a truck that stops,
reverses or changes speed over a card stretches its windows out of step, and would misread L1 as L3
(recognition_bench --motion).

In forward travel a card crosses the image from C1 to C4 (world marker_sensor), so a column sees
its C4 element first. In reverse the read is mirrored, and no mirrored navigating card is a
template (78H -> E1H, 3CH -> C3H, 5AH -> A5H, 1EH -> 87H, A3H -> C5H): a reversing truck recognises
nothing (it only reverses positioning).
"""

from dataclasses import dataclass, field
from itertools import pairwise

ELEMENTS = 4  # elements of a navigating-table card along the track (Baker 1983, 4.3)
LEVEL = 0.5  # the middle of the invalid band, in band units (0 = THROFF, 1 = THRON)
# Adjacent columns' windows open one element apart; with +-3 mm detector skew the three delays
# of a clean pass differ by up to 1.9x (2,400 passes at 1 and 2 m/s); a stop between two
# columns' openings makes one delay many times the others.
DELAY_SPREAD = 2.5
LONGEST = 2000  # snapshots (5.9 s): a window this long is given up (truck at rest on a card)


@dataclass
class _Column:
    """One detector column's window on the passing card."""

    armed: bool = False  # its presence has been low since the last reset
    rise: float | None = None  # sample index where the window opened (interpolated)
    fall: float | None = None  # where it last closed
    low: int = 0  # snapshots since it last closed
    start: int = 0  # sample index of rows[0]
    rows: list[tuple[float, float]] = field(default_factory=list)  # (R1, R2) band units


class SequenceDecoder:
    """Snapshots in (as band-unit values per detector), recognitions (CODE) out."""

    def __init__(self, templates: dict[int, int], agree: int = 3, margin: float = 0.25,
                 stretch: float = 1.5) -> None:
        self.templates = templates  # CODE -> identity
        self.agree, self.margin = agree, margin
        # A window may be up to `stretch` times longer or shorter than four column delays (in
        # 24,000 clean reads at 1 and 2 m/s across 280-320 mm: 0.83-1.30; the misreads: 2.5).
        self.stretch = stretch
        self.passage = 0
        self.reset()

    def reset(self) -> None:
        """Start afresh on a new table or a filter reset: a card already in view is not read."""
        self._columns = [_Column() for _ in range(4)]
        self._sample = -1
        self._before: list[float] | None = None  # the previous snapshot
        self._open, self._all_armed = 0, False  # _open: columns with a window open
        self._new_passage()

    def _new_passage(self) -> None:
        self.passage += 1  # the card now passing (numbered, for the caller's bookkeeping)
        self._rises: list[float | None] = [None] * 4
        self._reads: list[tuple[int | None, float]] = []  # (CODE or None, window length)
        self._reported = False

    def sample(self, z: list[float]) -> int | None:
        """Take a snapshot, z[d] = (TOTAL - THROFF) / (THRON - THROFF); a CODE when one is read."""
        self._sample += 1
        before, self._before = self._before, z
        if self._open == 0 and max(z) <= LEVEL:  # nothing white in view: the usual case
            if not self._all_armed:
                for col in self._columns:
                    col.armed = True
                self._all_armed = True
            return None
        i, out = self._sample, None
        for c, col in enumerate(self._columns):
            pair = (z[c], z[c + 4])
            p = pair[0] if pair[0] > pair[1] else pair[1]  # white in either row
            last = None if before is None else max(before[c], before[c + 4])
            if col.rise is None:
                if p <= LEVEL:
                    col.armed = True
                elif col.armed and before is not None and last is not None and last <= LEVEL:
                    if self._open == 0:
                        self._new_passage()
                    col.rise = i - 1 + (LEVEL - last) / (p - last)
                    col.fall, col.low, col.start = None, 0, i - 1
                    col.rows = [(before[c], before[c + 4]), pair]
                    self._rises[c] = col.rise
                    self._open += 1
                else:
                    self._all_armed = False  # white since before it was armed
                continue
            col.rows.append(pair)
            if last is None:  # a window opens only on a snapshot that had one before it
                raise RuntimeError('sequence decoder: an open window without a snapshot before')
            if p > LEVEL:
                col.fall, col.low = None, 0
                if len(col.rows) > LONGEST:  # at rest on a card: give the window up
                    col.rise, col.armed, self._all_armed = None, False, False
                    self._open -= 1
                continue
            if col.fall is None:
                col.fall = i - 1 + (last - LEVEL) / (last - p)
            col.low += 1
            # A card may be black in both rows for one element inside (the stop centre view):
            # the window closes after 1.5 elements of black.
            if col.low > 1.5 * self._element(col.rise, col.fall) + 1:
                self._reads.append((self._read(col, col.rise, col.fall), col.fall - col.rise))
                col.rise = None
                self._open -= 1
                out = self._verdict() if out is None else out
        return out

    def _column_delay(self) -> float | None:
        """Snapshots between adjacent columns' windows opening (one element's travel)."""
        r = self._rises
        gaps = [b - a for a, b in pairwise(r) if a is not None and b is not None and b > a]
        return sum(gaps) / len(gaps) if gaps else None

    def _element(self, rise: float, fall: float) -> float:
        """Snapshots per element: the column delay, or a quarter of this window so far."""
        delay = self._column_delay()
        return delay if delay is not None else (fall - rise) / ELEMENTS

    def _read(self, col: _Column, rise: float, fall: float) -> int | None:
        """Return one column's CODE (C1 in each nibble's bit 3); None if unsure (`margin`)."""
        length = fall - rise
        if length < 2.0:
            return None
        element, code = length / ELEMENTS, 0
        for row in (0, 1):
            bits = 0
            for j in range(ELEMENTS):  # time order: C4's element first
                t = rise + (j + 0.5) * element - col.start
                k = int(t)
                if k + 1 >= len(col.rows):
                    return None
                f = t - k
                v = col.rows[k][row] * (1.0 - f) + col.rows[k + 1][row] * f
                if abs(v - LEVEL) < self.margin:
                    return None
                bits |= (v > LEVEL) << j  # C4 -> bit 0 ... C1 -> bit 3
            code = code << 4 | bits
        return code

    def _verdict(self) -> int | None:
        if self._reported:
            return None
        clean = [(code, n) for code, n in self._reads if code is not None]
        if len(clean) < self.agree or any(code != clean[0][0] for code, _n in clean) \
                or clean[0][0] not in self.templates:
            return None
        delay = self._column_delay()
        r = self._rises
        gaps = [b - a for a, b in pairwise(r) if a is not None and b is not None]
        if len(gaps) > 1 and max(gaps) > DELAY_SPREAD * min(gaps):
            return None
        if delay is None or any(not 1.0 / self.stretch <= n / (ELEMENTS * delay) <= self.stretch
                                for _code, n in clean):
            return None
        self._reported = True
        return clean[0][0]
