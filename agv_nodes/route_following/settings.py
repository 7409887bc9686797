"""Route following settings, declared in its parameters.yaml; nested groups give `wire.kp` etc."""

from typing import Any

from agv_nodes.records import codec
from agv_nodes.route_following.dead_reckoning import trajectory_conic
from agv_nodes.settings import settings_class

# The track identification's groups: settings_class finds a nested group by name in this module.
from agv_nodes.track_geometry.settings import FeedForwardParams, IdentificationParams

__all__ = ['CalibrationParams', 'Chapter9Params', 'DeadReckoningParams', 'DriveSafetyParams',
           'DualCameraParams', 'FeedForwardParams', 'IdentificationParams', 'ImageParams',
           'ManualParams', 'RouteParams', 'SteeringParams', 'TurningParams', 'WireParams']


@settings_class
class WireParams:
    """Guide-wire steering (Baker 1983, 3.5.3, 6.2.1, 7.2; tuned in bench/route_bench.py)."""


@settings_class
class ImageParams:
    """Camera window calibration and noise filter (Rajagopalan 1991, 4.2, Table 6.1, App. F.2)."""


@settings_class
class SteeringParams:
    """Camera steering laws and the CONCIC-II geometry (Rajagopalan 1991, 5.2; Table 6.1)."""


@settings_class
class TurningParams:
    """Taking a branch at a road sign (App. F.6, which leaves the spin in place assumed here)."""


@settings_class
class DualCameraParams:
    """Gains and options of the dual-camera law (agv_nodes/route_following/dual_camera.py).

    Gains are rad of caster angle per m of offset (per rad for G2), as the single-camera law's.
    The thesis gives its simulation gains only inside Figs. 7.13-7.14 and found them by trial
    and error (Sec. 7.4); so were these, on the kinematic CONCIC-II at 0.47 m/s
    (bench/dual_camera_bench.py shows the result and the trade-off). Both extra terms equal
    e_df + e_dr whenever their law applies, so with the caster law psi' = V theta_s / L_a each
    law is linear in the axle's offset y and heading psi along the track: per metre travelled,
    y'' + (G L_c / L_a) y' + ((G + 2 Gx) / L_a) y = 0, G = G1 or G4 and Gx = G3 or G5. The
    straight start gains put both roots at 4.2 per m with damping 0.86, the low ones at 3.2
    per m with damping 0.82. law = pose steers by our law instead (dual_pose_law.py, keys
    pose_*; L_c is TurningParams camera_ahead), tuned on the same bench on both CONCIC-II models.
    """


@settings_class
class ObstacleStopParams:
    """The ultrasonic obstacle stop (Rajagopalan 1991, 6.3.11; obstacle_stop.py)."""


@settings_class
class DriveSafetyParams:
    """The software checks of the safety supervisor (Rajagopalan 1991, 6.3.11; drive_safety.py)."""


@settings_class
class DeadReckoningParams:
    """Dead reckoning along a stored trajectory (Rajagopalan 1991, App. F.9; dead_reckoning.py)."""


@settings_class
class ManualParams:
    """Manual driving from cmd_vel, its limits and watchdog (Rajagopalan 1991, App. F.4)."""


@settings_class
class CalibrationParams:
    """Camera calibration against the known tape (Rajagopalan 1991, App. F.3; calibration.py)."""


@settings_class
class Chapter9Params:
    """Rajagopalan 1991, Chapter 9's proposals on the camera law, all off (chapter9.py)."""


@settings_class
class RouteParams:
    """All route-following settings."""

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks `build` needs beyond each field's own: the stored trajectories."""
        stored = self.dead_reckoning.trajectories
        most = codec()['route_command'].field('trajectory').hi  # what a leg can name
        if len(stored) > most:
            return [('dead_reckoning.trajectories', list(stored),
                     f'at most {most} (a task names them 1-{most})')]
        for text in stored:
            try:
                trajectory_conic(text)
            except ValueError as exc:
                return [('dead_reckoning.trajectories', list(stored), str(exc))]
        return []
