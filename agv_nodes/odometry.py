"""The wheel encoders' distance, as traction and navigation both count it.

wheel_odometry carries each driven wheel's travel as a wrapping 16-bit mm counter. Counting it,
rather than integrating the speed over a nominal loop period, is exact however the ticks fall:
under sim time a timer fires at most once per /clock step, and skipped ticks lose distance.
"""


def counter_step(before: int, after: int) -> int:
    """Signed mm between two readings of a wrapping u16 mm counter (|step| < 32.768 m)."""
    return (after - before + 0x8000) % 0x10000 - 0x8000


class Odometer:
    """Distance travelled by each driven wheel and by the truck's centre (their mean), m."""

    def __init__(self) -> None:
        self.left = self.right = 0.0
        self._last: tuple[int, int] | None = None

    @property
    def metres(self) -> float:
        """The centre's travel, m."""
        return (self.left + self.right) / 2.0

    def update(self, left_mm: int, right_mm: int) -> float:
        """Take one reading of the two counters; returns the centre's distance so far."""
        if self._last is not None:
            self.left += counter_step(self._last[0], left_mm) / 1000.0
            self.right += counter_step(self._last[1], right_mm) / 1000.0
        self._last = (left_mm, right_mm)
        return self.metres
