"""The wheel-level loops Rajagopalan 1991 proposed in 9.2 (system 15), around the LM628s.

The thesis built neither; both act on the dynamic CONCIC-II (concic2_dynamics.py), each behind a
world option that is off at 0 (concic2.cross_coupling, concic2.cartesian_gain). At each servo
sample they shift what each chip reads of its encoder, so that the chip's position error becomes
its own plus a correction (counts): the chips' PID filters and gains stay the thesis's (7.3).

- Cross-coupled loop (9.2.1, Fig. 9.1, after Borenstein and Koren 1987): "the error from wheel-2
  is fed to the wheel-1 loop, and vice versa". The contour error, e1 - e2 weighted by each
  wheel's share of the motion (cross_coupled_error), times cross_coupling, is added to wheel
  1's error and taken from wheel 2's: the wheel that lags pushes, the other waits, and the pair
  stays in step (at the cost of lag, 9.2.1).
- Cartesian loop (9.2.2, Fig. 9.2): the virtual reference point moves along where the truck is
  meant to be. Here [A] it is the pose the chips' desired positions dead-reckon (the profile
  followed exactly), the actual pose the encoders'; both start where the chips start. The error
  in the truck's frame (along, across, heading) times cartesian_gain becomes rim metres on each
  wheel: along on both, and the turn heading + across / L (L the wheel span [A]) as the
  differential +-L/2 of it.

Errors are read before the sample's profile step (desired as it stood): one sample, 341 us, old.
"""

from __future__ import annotations

import math

from agv_nodes.world.lm628 import LM628


def cross_coupled_error(left_error: float, right_error: float, left_share: float = 0.5
                        ) -> float:
    """Return the cross-coupling error of 9.2.1 (Fig. 9.1): each wheel's error fed to the other.

    With the wheels' tracking errors (desired - actual position) e1, e2 and a path that needs
    them in the ratio of their speeds, the contour error is e1 - e2 weighted by each wheel's
    share of the motion (Borenstein and Koren's form for the thesis's equal wheels: e1 - e2).
    Added to wheel 1's loop and subtracted from wheel 2's, it drives the pair back into step.
    """
    return 2.0 * ((1.0 - left_share) * left_error - left_share * right_error)


def cartesian_error(pose: tuple[float, float, float], reference: tuple[float, float, float]
                    ) -> tuple[float, float, float]:
    """Return the pose error to the virtual reference point of 9.2.2, in the truck's frame.

    (along, across, heading): the reference point moves along the track where the truck is
    meant to be; its lead `along` > 0 is the servo lag the Cartesian loop takes out.
    """
    x, y, heading = pose
    rx, ry, rheading = reference
    c, s = math.cos(heading), math.sin(heading)
    dx, dy = rx - x, ry - y
    turn = math.atan2(math.sin(rheading - heading), math.cos(rheading - heading))
    return c * dx + s * dy, -s * dx + c * dy, turn


def _advance(pose: list[float], d_left: float, d_right: float, span: float) -> None:
    """Dead-reckon `pose` (x, y, heading) over rim travels d_left, d_right (m), midpoint rule."""
    turn = (d_right - d_left) / span
    mid = pose[2] + 0.5 * turn
    along = 0.5 * (d_left + d_right)
    pose[0] += along * math.cos(mid)
    pose[1] += along * math.sin(mid)
    pose[2] += turn


class WheelLoops:
    """The corrections (counts) the two loops add to the chips' position errors each sample."""

    def __init__(self, cross_coupling: float, cartesian_gain: float, span: float,
                 counts_per_m: float) -> None:
        self.cross_coupling, self.cartesian_gain = cross_coupling, cartesian_gain
        self.span, self.counts_per_m = span, counts_per_m
        self.actual: list[float] | None = None  # the encoders' pose, m, m, rad
        self.reference: list[float] | None = None  # the virtual reference point's
        self._last = (0, 0, 0, 0)  # desired and actual counts, left and right

    def reset(self) -> None:
        """Forget the poses (the chips are off: they restart from where the wheels are)."""
        self.actual = self.reference = None

    def corrections(self, left: LM628, right: LM628, pos1: int, pos2: int) -> tuple[int, int]:
        """Return what to add to each chip's position error (counts) at this sample."""
        d1, d2 = left.desired >> 16, right.desired >> 16
        c1 = c2 = 0.0
        if self.cross_coupling:
            # Each wheel's share of the motion (the profiles' speeds): a steady turn's lags,
            # each in proportion to its wheel's speed, leave no contour error.
            v1, v2 = abs(left.profile), abs(right.profile)
            share = v1 / (v1 + v2) if v1 + v2 else 0.5
            cc = self.cross_coupling * cross_coupled_error(d1 - pos1, d2 - pos2, share)
            c1, c2 = cc, -cc
        if self.cartesian_gain:
            if self.actual is None or self.reference is None:
                self.actual, self.reference = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
                self._last = (d1, d2, pos1, pos2)
            q1, q2, p1, p2 = self._last
            k = 1.0 / self.counts_per_m
            _advance(self.reference, (d1 - q1) * k, (d2 - q2) * k, self.span)
            _advance(self.actual, (pos1 - p1) * k, (pos2 - p2) * k, self.span)
            self._last = (d1, d2, pos1, pos2)
            along, across, heading = cartesian_error(
                (self.actual[0], self.actual[1], self.actual[2]),
                (self.reference[0], self.reference[1], self.reference[2]))
            turn = heading + across / self.span
            g = self.cartesian_gain * self.counts_per_m
            c1 += g * (along - 0.5 * self.span * turn)
            c2 += g * (along + 0.5 * self.span * turn)
        return int(round(c1)), int(round(c2))
