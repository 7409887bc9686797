"""Choice of the track model in use, and resets between the primitives of a route.

Rajagopalan 1991, 5.4.2 and 7.5.1.3: the three least-squares fits of fitting.py all take every
point P; the fitter says which one the feed-forward law should use and restarts them when the
track changes under them. ROS-free.
"""

from __future__ import annotations

import math

from agv_nodes.track_geometry.fitting import Conic, ConicFit, LineFit, PolynomialFit, Sample
from agv_nodes.track_geometry.settings import IdentificationParams


class TrackFitter:
    """The thesis's identification: the model chosen, its fit, and resets between primitives.

    Every sample goes to all three fits (each O(1)); `model` says which one is in use. For
    the first `switch_distance` m since the start (or a reset) that is the polynomial, as
    Rajagopalan 1991, 7.5.1.3 advises for a straight track, whose line fit starts with huge
    values; then the chosen model: line, conic, or (auto) whichever of the two has the smaller
    residual RMS, the line on a tie (it has fewer parameters). A model that has no solution
    yet leaves the polynomial in use. The thesis fits all data since the start (memory all);
    a route of lines and arcs needs a sliding window or a reset: with reset_residual > 0,
    reset_samples consecutive samples farther than it from the model in use restart all fits.
    """

    def __init__(self, params: IdentificationParams | None = None) -> None:
        self.params = p = params if params is not None else IdentificationParams()
        window = p.window if p.memory == 'window' else None
        self.polynomial = PolynomialFit(window, p.max_condition)
        self.line = LineFit(window, p.max_condition, p.line_form)
        self.conic = ConicFit(window, p.max_condition)
        self.resets = 0  # automatic ones
        self.reset()

    def reset(self) -> None:
        """Start all fits afresh (a new primitive of the route)."""
        for fit in (self.polynomial, self.line, self.conic):
            fit.reset()
        self._start: float | None = None
        self._s, self._latest, self._strikes = 0.0, (0.0, 0.0, 0.0), 0

    def add(self, x: float, y: float, theta_p: float, s: float) -> None:
        """Take the point P, the track's heading there and the distance travelled (m)."""
        limit = self.params.reset_residual
        if limit > 0.0:
            fit = self.fit
            err = None if fit is None else fit.error(Sample(s, x, y, theta_p))
            self._strikes = self._strikes + 1 if err is not None and err > limit else 0
            if self._strikes >= self.params.reset_samples:
                self.reset()
                self.resets += 1
        if self._start is None:
            self._start = s
        self._s, self._latest = s, (x, y, theta_p)
        self.polynomial.add(x, y, s)
        self.line.add(x, y, s)
        self.conic.add(x, y, theta_p, s)

    @property
    def travelled(self) -> float:
        """Return the distance since the start or the last reset, m."""
        return 0.0 if self._start is None else self._s - self._start

    @property
    def model(self) -> str | None:
        """Return the model in use (polynomial, line or conic); None before any has a fit."""
        p = self.params
        names = ['polynomial']
        if p.model != 'polynomial' and self.travelled >= p.switch_distance:
            names = ['line', 'conic'] if p.model == 'auto' else [p.model]
        scored = [(rms, i, name) for i, name in enumerate(names)
                  if (rms := getattr(self, name).residual_rms) is not None]
        if scored:
            return min(scored)[2]
        return 'polynomial' if self.polynomial.ready else None

    @property
    def fit(self) -> PolynomialFit | LineFit | ConicFit | None:
        """Return the fit in use."""
        return None if (name := self.model) is None else getattr(self, name)

    def implicit(self) -> Conic | None:
        """Return the implicit curve of the model in use, its sign set by the travel.

        The tangent (f_y, -f_x) at the latest P points along the track's heading there: the
        fits' own forms have an arbitrary overall sign.
        """
        if (fit := self.fit) is None or (conic := fit.implicit()) is None:
            return None
        A, B, C, D, E, F = conic
        x, y, theta = self._latest
        fx, fy = 2 * A * x + B * y + D, B * x + 2 * C * y + E
        return (-A, -B, -C, -D, -E, -F) if fy * math.cos(theta) < fx * math.sin(theta) else conic

    @property
    def residual_rms(self) -> float | None:
        """Return the residual RMS of the model in use, m."""
        return None if (fit := self.fit) is None else fit.residual_rms

    @property
    def ready(self) -> bool:
        """Whether the identification has converged enough to steer by.

        At least ready_distance m since the start or the last reset, the model in use holding
        ready_samples samples, and its residual RMS within ready_residual. The thesis judged
        convergence by eye on its plots of the coefficients (Rajagopalan 1991, 7.5.1.4,
        7.5.2.5); this is the test a running truck can make. An automatic reset (a new
        primitive) makes it false again until the new fit passes.
        """
        p, fit = self.params, self.fit
        if fit is None or self.travelled < p.ready_distance or fit.n < p.ready_samples:
            return False
        rms = fit.residual_rms
        return rms is not None and rms <= p.ready_residual
