"""Feed-forward steering on the identified track (Rajagopalan 1991, 5.4.5-5.4.6, Eq. 5.89-5.91).

Each sample the identification gives the osculating circle of the track at the point the
camera will see next (radius R_1 and the side of its centre; osculating.py), the driving
criterion turns it into the offsets the window should read (eps_dd, eps_thetad; criteria.py),
and this law steers the caster angle theta_s so that the measured offsets (eps_da,
eps_thetaa) reach them. The thesis never ran the law (its 80286 was too slow, 7.6) and gives
no gains.

Deviations (Eq. 5.90-5.91):

    delta_eps_d(n+1)     = eps_dd(n+1)     - eps_da(n)
    delta_eps_theta(n+1) = eps_thetad(n+1) - eps_thetaa(n)

Eq. 5.91 is printed with eps_thetad(n) as its second term; the measured eps_thetaa(n) is
meant, as in Eq. 5.90 and the text around them.

Sign. With the package's signs (eps_d > 0: the tape left of the window centre; eps_theta > 0:
the tape turned counter-clockwise; theta_s > 0 turns left) the truck must turn left when the
tape is further left than desired, that is when delta_eps_d < 0: Eq. 5.89 as printed would need
negative gains. The law here is written on e = measured - desired = -delta_eps so that its
gains are positive, as those of the P and PI laws (Eq. 5.4, 5.6) are. The closed loops of
test/test_feed_forward.py check it: on a circle the truck converges to (eps_dd, eps_thetad).

Forms (`FeedForwardParams.form`):

incremental  Eq. 5.89 as printed, the caster angle moved each sample by
                 theta_s(n+1) = theta_s(n) + G1 e_d + G2 e_theta + G3 sum(e_d dT)
             It would hold a curve without knowing its curvature (the increments stop when
             e = 0), but each term is one integration more than it looks, and the loop is
             unstable whatever the gains. Per metre travelled, with the caster law
             psi' = v theta_s / L_a, O's offset y and heading psi from the desired path
             (e_d = -(y + L_c psi), e_theta = -psi) and k_i = G_i / (v dT), G3 = 0:
                 y''' + ((k1 L_c + k2) / L_a) y' + (k1 / L_a) y = 0
             has no y'' term, so its roots sum to zero: beside a real root decaying at about
             G1 / (G1 L_c + G2) per metre a pair grows at half that, at any speed. G1 = 0
             leaves an undamped swing and no hold on eps_d (on a circle eps_theta does not
             depend on where O runs), and with eps_theta unused (G2 = 0, as in the thesis's
             runs, 9.1) the tape leaves the window within 3-7 m; G3 adds one more
             integration. The velocity form of the PI law, Eq. 5.8, differences the offsets
             between samples, which makes it the positional PI law; Eq. 5.89 does not. Kept
             to show what the printed law does.
positional   theta_s = theta_ff + G1 e_d + G2 e_theta + G3 sum(e_d dT), where theta_ff is the
             caster angle that by itself holds the truck on the criterion's circle (Eq.
             5.10-5.11 solved for the osculating circle, `feed_forward_angle`). The feedback
             only corrects the deviations, so it is the P / PI law of 5.2 around the curve's
             own steering: on a circle it settles on the desired offsets with no integral
             at all, and the integral removes only what the model misses (a wrong L_a, unequal
             wheels). The form we expect to work better, and the default.

chord        (chord_law.py, ours) steers by the track points themselves, not by this law: it
             holds the body on the chord of the points that both caster contacts should touch.
             The identified conic and this law's positional form steer only where it cannot.

Gains: rad of caster angle per m of e_d (G1), per rad of e_theta (G2), per m s of the integral
(G3) in the positional form; in the incremental form the same per sample. The positional
feedback alone gives, per metre, y'' + ((G1 L_c + G2) / L_a) y' + (G1 / L_a) y = 0 at any
speed: G1 = 4 L_a / L_c^2 = 3.0 rad/m makes it critically damped on eps_d alone (the P law's
2.5 gives 0.9 of critical), G2 = 0.4 adds damping (1.2 of critical) as margin for the frame
and drive delays, and G3 = 1.0 removes the error a wrong L_a leaves. They were chosen by
closed-loop simulation of a kinematic CONCIC-II (Eq. 5.10-5.11, dT = 50 ms, exact camera
geometry) on the R = 2.95 m circle at 0.3, 0.6 and 0.9 m/s, from O on the track, 3 cm either
side of it or 0.03 rad askew, with L_a 3 cm longer on the truck than in the law or the command
100 ms late, over G1 in 1.5-6, G2 in 0-1 and G3 in 0-2. With these eps_d settled within 2 mm
of eps_dd within 2.2 m of travel in every case (the slowest: the wrong L_a at 0.9 m/s, which
only the integral removes; a larger G3 is faster there but overshoots more elsewhere) and
overshot by at most 6 mm, or 31 mm with the command 100 ms late at 0.9 m/s from 46 mm off.
test/test_feed_forward.py runs that loop. The incremental defaults are among the slowest to
diverge.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

from agv_nodes.settings import build, values_of
from agv_nodes.track_geometry.criteria import (
    CAMERA_AHEAD,
    CASTER_DISTANCE,
    desired_offsets,
    path_radius,
)
from agv_nodes.track_geometry.settings import FeedForwardParams


@dataclass(frozen=True)
class Geometry:
    """The truck's dimensions the law needs, m (and its caster angle limit, rad).

    Not settings of the law: the truck's own, given by whoever drives it (route following takes
    them from its steering and turning groups, so there is one source for each).
    """

    camera_ahead: float = CAMERA_AHEAD  # L_c: the camera window's centre ahead of the axle
    caster_distance: float = CASTER_DISTANCE  # L_a: from the axle to a caster contact
    caster_trail: float = 0.05  # s of Eq. 5.11
    max_angle: float = math.pi / 3  # the caster angle's limit, rad

    def __post_init__(self) -> None:
        if not (self.caster_distance > 0.0 and self.caster_trail >= 0.0
                and self.max_angle > 0.0):
            raise ValueError(f'{self} is no truck: L_a and the angle limit must be positive, '
                             'the trail not negative')


def effective_wheelbase(theta_s: float, caster_distance: float, caster_trail: float) -> float:
    """L_ae = L_a + s (1 - cos theta_s) (Eq. 5.11)."""
    return caster_distance + caster_trail * (1.0 - math.cos(theta_s))


def feed_forward_angle(radius: float, side: int, params: FeedForwardParams | None = None,
                       geometry: Geometry | None = None) -> float:
    """Caster angle that alone keeps the truck on the criterion's circle about the centre.

    The axle centre O runs on rho = criteria.path_radius(R_1, criterion), so the yaw rate is
    v / rho and Eq. 5.10 gives tan(theta_s) = L_ae(theta_s) / rho; L_ae changes by s (1 - cos)
    only, and a few fixed-point steps solve it to rounding. side +1: centre on the left.
    """
    p, g = params or FeedForwardParams(), geometry or Geometry()
    rho = path_radius(radius, p.criterion, camera_ahead=g.camera_ahead,
                      caster_distance=g.caster_distance, half_length=p.half_length)
    if not math.isfinite(rho) or side == 0:
        return 0.0
    if rho <= 0.0:
        return math.copysign(math.pi / 2.0, side)
    theta = math.atan(g.caster_distance / rho)
    for _ in range(4):
        theta = math.atan(effective_wheelbase(theta, g.caster_distance, g.caster_trail) / rho)
    return theta if side > 0 else -theta


class FeedForwardSteering:
    """The law of Eq. 5.89-5.91, incremental or positional; one `update` per camera sample.

    Under form chord it is the positional law, for what the chord law leaves to the conic.
    """

    def __init__(self, params: FeedForwardParams | None = None,
                 geometry: Geometry | None = None) -> None:
        self.p = params or FeedForwardParams()
        build(FeedForwardParams, values_of(self.p))  # SettingError: a value out of its range
        self.geometry = geometry or Geometry()
        self.theta_s = 0.0
        self.integral = 0.0  # m s: sum of e_d dT

    def reset(self, theta_s: float = 0.0) -> None:
        """Start again from caster angle `theta_s` with an empty integral."""
        self.theta_s = theta_s
        self.integral = 0.0

    def desired(self, radius: float, side: int) -> tuple[float, float]:
        """(eps_dd, eps_thetad) for the osculating circle (radius R_1, centre side)."""
        p, g = self.p, self.geometry
        return desired_offsets(radius, side, p.criterion, camera_ahead=g.camera_ahead,
                               caster_distance=g.caster_distance, half_length=p.half_length)

    def update(self, eps_d: float, eps_theta: float, radius: float, side: int,
               dt: float, share: float = 1.0) -> float:
        """Return the caster angle for the next sample.

        eps_d, eps_theta: the offsets measured now (eps_da(n), eps_thetaa(n)); radius, side:
        the osculating circle where the camera will look next (R_1 at (n+1) dT; inf for a
        straight track); dt: the sample period. `share` (0-1) of eps_dd is aimed at: the
        window criterion's 0 blended into the criterion's own, for a law that takes over from
        one that held the window on the tape (every criterion has the same eps_thetad).
        """
        p = self.p
        eps_dd, eps_thetad = self.desired(radius, side)
        e_d = eps_d - share * eps_dd  # -delta_eps_d(n+1), Eq. 5.90
        e_theta = eps_theta - eps_thetad  # -delta_eps_theta(n+1), Eq. 5.91
        self.integral += e_d * dt
        if p.form == 'incremental':
            theta = self.theta_s + (p.step_gain_d * e_d + p.step_gain_theta * e_theta
                                    + p.step_gain_i * self.integral)
        else:
            theta = (feed_forward_angle(radius, side, p, self.geometry) + p.gain_d * e_d
                     + p.gain_theta * e_theta + p.gain_i * self.integral)
        limit = self.geometry.max_angle
        self.theta_s = max(-limit, min(limit, theta))
        return self.theta_s
