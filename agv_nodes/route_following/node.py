"""route_following: guide wire, SRMs and binary-camera guidance (ros2 run agv_nodes
route_following).

Reads route/command, hw/guide_wire, hw/wheel_odometry and hw/camera/front (sensor_msgs/Image,
mono8, tape dark); writes hw/steering/command and route/status. Behaviour:
`agv_nodes.route_following.core`.
"""

from __future__ import annotations

import sys

import numpy as np
from sensor_msgs.msg import Image

from agv_nodes import qos
from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.params import Parameters
from agv_nodes.route_following.camera_guidance import ImageParams, SteeringParams
from agv_nodes.route_following.core import RouteCore, RouteParams, TurningParams, WireParams


class RouteFollowingNode(CoreNode):
    """Parameters -> RouteCore -> ports (+ the camera frames)."""

    def __init__(self) -> None:
        super().__init__('route_following')
        p = Parameters(self)
        dw, ds, di = WireParams(), SteeringParams(), ImageParams()
        wire = WireParams(
            kp=p.number('wire_kp', dw.kp, 'guide wire: rad of steering per m of offset', 0.0,
                        200.0),
            ki=p.number('wire_ki', dw.ki, 'guide wire: rad per m s of integrated offset', 0.0,
                        200.0),
            kd=p.number('wire_kd', dw.kd, 'guide wire: rad per m/s of offset rate', 0.0, 50.0),
            nominal=p.number('wire_nominal', dw.nominal, 'coil reading over the wire (counts, '
                             'calibration)', 10.0, 4095.0),
            lost_level=p.number('wire_lost_level', dw.lost_level, 'fraction of nominal below '
                                'which the wire is lost', 0.01, 1.0),
            lost_samples=p.integer('wire_lost_samples', dw.lost_samples, 'consecutive weak '
                                   'samples before LOST', 1, 100),
            srm_timeout=p.number('srm_timeout', dw.srm_timeout, 's an SRM may search', 1.0,
                                 120.0),
        )
        steering = SteeringParams(
            law=p.choice('camera_law', ds.law, 'camera steering law (thesis Eq 5.4 / 5.6)',
                         ('p', 'pi')),
            gain_d=p.number('camera_gain_d', ds.gain_d, 'rad per m of eps_d (thesis 2.5)', 0.0,
                            100.0),
            gain_theta=p.number('camera_gain_theta', ds.gain_theta, 'rad per rad of eps_theta',
                                0.0, 10.0),
            gain_i=p.number('camera_gain_i', ds.gain_i, 'integral gain (thesis 0.07)', 0.0,
                            100.0),
            integral_form=p.choice('camera_integral', ds.integral_form, 'integral term: per '
                                   'frame as Eq 5.8 is printed, or x Delta-T as in Eq 5.6',
                                   ('per_frame', 'with_dt')),
            schedule_speed=p.number('camera_schedule_speed', ds.schedule_speed, 'above this '
                                    'cruise the eps_d gain falls as 1/speed, m/s (0: off, the '
                                    'thesis)', 0.0, 2.0),
            integral_band=p.number('camera_integral_band', ds.integral_band, 'the integral '
                                   'gathers only while |eps_d| is within this, m (0: always, '
                                   'the thesis)', 0.0, 0.2),
            set_off_acceleration=p.number('camera_set_off_acceleration',
                                          ds.set_off_acceleration, 'speed ramp asked for when '
                                          'setting off from rest, m/s^2 (0: cruise at once)',
                                          0.0, 2.0),
        )
        dt_ = TurningParams()
        turning = TurningParams(
            crossing_from=p.choice('junction_crossing_from', dt_.crossing_from, 'where the '
                                   'axle stops to turn: at the crossing placed from the image, '
                                   'or L_c past the sighting (thesis App. F.6)',
                                   ('image', 'thesis')),
            approach_speed=p.number('junction_approach_speed', dt_.approach_speed, 'm/s once '
                                    'the chosen branch is in sight', 0.02, 1.0),
            spin_speed=p.number('junction_spin_speed', dt_.spin_speed, 'wheel speed of the '
                                'spin onto a branch, m/s', 0.02, 0.5),
        )
        image = ImageParams(min_run=p.integer('camera_min_run', di.min_run, 'noise filter: '
                                              'shortest track run, px (thesis 16)', 1, 64))
        rp = RouteParams(
            vehicle=p.choice('vehicle', 'electruk', 'steering output: Ackermann angle or '
                             'differential wheel speeds', ('electruk', 'concic2')),
            camera_speed=p.number('camera_speed', RouteParams().camera_speed, 'cruise speed in '
                                  'camera mode, m/s', 0.0, 1.2),
            wire=wire, image=image, steering=steering, turning=turning)
        self.attach(RouteCore(rp), p)
        self.create_subscription(Image, 'hw/camera/front', self._frame, qos.STREAM_READER)

    def _frame(self, msg: Image) -> None:
        if msg.encoding != 'mono8' or msg.height * msg.width != len(msg.data):
            self.get_logger().warn(f'camera frame rejected: {msg.encoding} '
                                   f'{msg.width}x{msg.height}', throttle_duration_sec=5.0)
            return
        pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width)
        frame = (pixels < 128).astype(np.uint8)  # dark tape = 1, as the optic-RAM gives it
        self.publish(self.core.on_frame(frame, self.now_s()))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes route_following [--ros-args ...]."""
    return spin_main(RouteFollowingNode, args)


if __name__ == '__main__':
    sys.exit(main())
