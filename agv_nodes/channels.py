"""The CONCIC-II's 12 software channels, logged every 50 ms and exported from a bag as CSV.

The thesis's data acquisition had, besides its hardware channels, "a total of 12 software
channels ... these channels store only the data that is computed and not by direct measurement"
(Rajagopalan 1991, 6.3.8), listed there in this order: the desired wheel speeds read from the
motion controllers, the actual wheel speeds read from the motion controllers, the actual speed
of the wheels (computed from the position counts and the cycle time by the slope method, 7.5.2.1,
since the LM628's velocity reads only to +-4.2 rpm), the front camera's offsets (eps_df,
eps_thetaf), the rear camera's (eps_dr, eps_thetar), the steering command from the cameras, and
the law in operation in dual-camera mode. Sampled every 50 ms (App. F.10: "The sampling interval
is 50 ms"). Each speed is a pair; the thesis names no order within it: wheel 1 (left) before
wheel 2 (right), as Eq. 3.63-3.65 number them.

Route following (the camera truck) keeps a ChannelLog and publishes each sample on
`route/channels` (std_msgs/Float64MultiArray: sim time, then the 12 channels, SI units:
m/s, m, rad; the law as its equation number, 5.19-5.22, 0 when the dual law is not steering);
the recorder keeps it in the bag like every topic. `agv-report --channels BAG [--out FILE]`
writes them as CSV (header `time_s` and the names below, one row per sample). A camera that sent
no frame, or whose last frame showed no tape, gives an empty cell (NaN), not a made-up zero.
The offsets are the camera's latest frame analysed as guidance analyses it
(camera_guidance.py), by the log's own analyser, so the camera that does not steer is logged
too (App. F.2 (8): "the unused one can still be logged"). Each is the camera's own reading: the
rear camera faces backwards, so its eps_d has the opposite sign of the forward frame's, its
eps_theta the same (dual_camera.travel_frame turns it for the law).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

# (name in the CSV header, what it is) in the thesis's order (Rajagopalan 1991, 6.3.8)
CHANNELS = (
    ('desired_speed_left', 'm/s, desired wheel speed (the demand sent to the motion controller)'),
    ('desired_speed_right', 'm/s'),
    ('controller_speed_left', 'm/s, actual wheel speed read from the motion controller'),
    ('controller_speed_right', 'm/s'),
    ('counted_speed_left', 'm/s, actual wheel speed from the position counts (slope, 7.5.2.1)'),
    ('counted_speed_right', 'm/s'),
    ('eps_df', 'm, front camera position offset'),
    ('eps_thetaf', 'rad, front camera orientation offset'),
    ('eps_dr', 'm, rear camera position offset'),
    ('eps_thetar', 'rad, rear camera orientation offset'),
    ('steering_command', 'rad, caster angle commanded from the camera information'),
    ('dual_law', 'equation of the dual-camera law in operation (5.19-5.22; 0: none)'),
)
NAMES = tuple(name for name, _ in CHANNELS)
SAMPLE_PERIOD = 0.05  # s (Rajagopalan 1991, App. F.10)
TOPIC = 'route/channels'


class ChannelLog:
    """Samples route following's software channels (RouteCore's state and the cameras' frames)."""

    def __init__(self, image_params: Any) -> None:
        from agv_nodes.route_following.camera_guidance import ImageAnalyser

        self._analysers = {c: ImageAnalyser(image_params) for c in ('front', 'rear')}
        self._frames: dict[str, np.ndarray] = {}
        self._counts: tuple[float, float, float] | None = None  # (t, left m, right m)

    def frame(self, frame: np.ndarray, camera: str) -> None:
        """Keep a camera's latest binary frame (analysed when a sample is taken)."""
        self._frames[camera] = frame

    def _offsets(self, camera: str) -> tuple[float, float]:
        from agv_nodes.route_following.camera_guidance import Validity

        frame = self._frames.get(camera)
        if frame is None:
            return math.nan, math.nan
        m = self._analysers[camera].analyse(frame)
        if m.validity in (Validity.ABSENT, Validity.SATURATED):
            return math.nan, math.nan
        return m.eps_d, m.eps_theta

    def sample(self, route: Any, now: float) -> list[float]:
        """Return [now, the 12 channels] from a RouteCore at sim time `now`."""
        command = route.steering_command()
        desired = (command['left_speed'] / 1000.0, command['right_speed'] / 1000.0) \
            if command['mode'] == 'wheel_speeds' else (math.nan, math.nan)
        # the slope method (7.5.2.1): the counts' change over the time between their readings
        odo, read_at = route.cam.odo, route.odometry_time
        counted = (math.nan, math.nan)
        if self._counts is not None and read_at is not None and read_at > self._counts[0]:
            t0, left0, right0 = self._counts
            counted = ((odo.left - left0) / (read_at - t0), (odo.right - right0) / (read_at - t0))
        if read_at is not None:
            self._counts = (read_at, odo.left, odo.right)
        law = route.cam.law
        dual = float(law.dual.decision.law.value) if (
            route.mode == 'camera' and law.law == 'dual' and route.motor_on) else 0.0
        steering = route.cam.steer if route.mode == 'camera' else 0.0
        return [now, *desired, *route.cam.rims, *counted, *self._offsets('front'),
                *self._offsets('rear'), steering, dual]


def read_channels(bag: Path) -> list[list[float]]:
    """Return the samples of `route/channels` in a bag (any namespace), in time order."""
    from rosbags.highlevel import AnyReader

    rows: list[list[float]] = []
    paths = [bag] + sorted(bag.parent.glob(f'{bag.name}_[0-9]*'))
    with AnyReader(paths) as reader:
        connections = [c for c in reader.connections
                       if c.topic == '/' + TOPIC or c.topic.endswith('/' + TOPIC)]
        for conn, _stamp, raw in reader.messages(connections=connections):
            # rosbags deserializes to `object`: the class is the connection's msgtype's
            msg: Any = reader.deserialize(raw, conn.msgtype)
            data = [float(v) for v in msg.data]
            if len(data) != 1 + len(CHANNELS):
                raise ValueError(f'{conn.topic}: a sample of {len(data)} values, not '
                                 f'{1 + len(CHANNELS)} (time and the 12 channels)')
            rows.append(data)
    return sorted(rows, key=lambda r: r[0])


def write_csv(rows: list[list[float]], out: Path) -> None:
    """Write the samples as CSV: `time_s` and the channels in the thesis's order."""
    with out.open('w', newline='') as f:
        writer = csv.writer(f)
        writer.writerow(('time_s', *NAMES))
        for row in rows:
            writer.writerow([f'{row[0]:.6f}'] + ['' if math.isnan(v) else f'{v:.6g}'
                                                 for v in row[1:]])


def export(bag: Path, out: Path | None = None) -> tuple[Path, int]:
    """Write `bag`'s software channels to `out` (default <bag>_channels.csv); (file, rows)."""
    rows = read_channels(bag)
    if not rows:
        raise ValueError(f'{bag}: no {TOPIC} samples (a camera truck records them)')
    out = out or bag.with_name(bag.name + '_channels.csv')
    write_csv(rows, out)
    return out, len(rows)
