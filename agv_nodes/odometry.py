"""The wheel encoders' distance, as traction and navigation both count it.

wheel_odometry carries each driven wheel's travel as a wrapping 16-bit mm counter (signed
travel, modulo 65536). Counting the counters, rather than integrating the speed over a nominal
loop period, is exact however the loop's ticks fall: under sim time over DDS a timer fires at
most once per /clock step, so ticks are skipped and speed x period loses distance.
"""

from __future__ import annotations


def counter_step(before: int, after: int) -> int:
    """Signed mm between two readings of a wrapping u16 mm counter (|step| < 32.768 m)."""
    return (after - before + 0x8000) % 0x10000 - 0x8000


class Odometer:
    """Distance travelled by the truck's centre, m (mean of the two wheels)."""

    def __init__(self) -> None:
        self.metres = 0.0
        self._last: tuple[int, int] | None = None

    def update(self, left_mm: int, right_mm: int) -> float:
        """Take one reading of the two counters; returns the distance so far."""
        if self._last is not None:
            self.metres += (counter_step(self._last[0], left_mm)
                            + counter_step(self._last[1], right_mm)) / 2000.0
        self._last = (left_mm, right_mm)
        return self.metres
