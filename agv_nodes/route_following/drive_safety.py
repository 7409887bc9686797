"""The software half of the CONCIC-II's safety supervisor (Rajagopalan 1991, 6.3.11), ROS-free.

The safety PAL (agv_nodes/world/safety_pal.py) cuts the amplifiers itself and says so in
drive_status; the computer's checks of 6.3.11 add what only the software can see:

- the PAL's latched faults, named: E-stop, watchdog timeout (CO-7), DAC over-voltage (CO-5),
  LM628 malfunction (CO-6), and an encoder that failed the PAL's start-up test; and the radio
  receiver's stop, which holds the power off while pressed (drive_status's radio_stop) and is
  latched here, as the encoder check's stop is, so that a released stop does not drive off;
- the encoder check during motion: a wheel asked to turn at `encoder_speed` or more whose
  encoder count has not moved for `encoder_time` ("Encoders Malfunctioning in Servo Loop #");
  only while the PAL reports ready, since unpowered wheels rightly stand still;
- the battery check: drive_status's battery below `battery_low` ("Battery Voltage
  Insufficient").

Any of them is a fault route following stops on, motor off, and names in route_status. The
PAL's faults and the battery are what drive_status says now (the PAL latches its own until a
hardware reset); a failed encoder and a radio stop are latched here until `clear()`, the
thesis's "a software-detected stop is cleared by reloading the software": route following
clears them when it leaves camera mode or begins a leg, and the checks find them again if they
are still there.
"""

from __future__ import annotations

from typing import Any

from agv_nodes.route_following.settings import DriveSafetyParams

FAULTS = ('none', 'estop', 'watchdog', 'over_voltage', 'controller', 'encoder_left',
          'encoder_right', 'battery_low', 'radio_stop')


def pal_fault(status: dict[str, Any], battery_low: float) -> str:
    """Name the fault a drive_status record reports ('none' when the drive is healthy)."""
    if status['estop']:
        return 'estop'
    if status.get('radio_stop'):  # the radio receiver's stop holds the power off
        return 'radio_stop'
    if status['watchdog']:
        return 'watchdog'
    if status['over_voltage']:
        return 'over_voltage'
    if status['controller_fault'] != 'none':
        return 'controller'
    if status['encoder_fault'] != 'none':  # the start-up test's small move gave no feedback
        return f'encoder_{status["encoder_fault"]}'
    if status['battery'] / 10.0 < battery_low:
        return 'battery_low'
    return 'none'


class DriveSafety:
    """See the module docstring; RouteCore feeds it drive_status and wheel_odometry."""

    def __init__(self, params: DriveSafetyParams) -> None:
        self.p = params
        self.status: dict[str, Any] | None = None  # the latest drive_status
        self.encoder = 'none'  # a wheel the encoder check found silent (latched)
        self.radio_stopped = False  # the radio stop was pressed (latched: released, the truck
        # stays stopped until reloaded, as a software-detected stop is)
        self._counts: list[int | None] = [None, None]  # each wheel's last distance counter
        self._silent_since: list[float | None] = [None, None]

    @property
    def fault(self) -> str:
        """The fault to stop on, the PAL's first (one of FAULTS)."""
        found = 'none' if self.status is None else pal_fault(self.status, self.p.battery_low)
        if found != 'none':
            return found
        return 'radio_stop' if self.radio_stopped else self.encoder

    def drive_status(self, fields: dict[str, Any]) -> None:
        """Take a drive_status record (a radio stop in it is latched until `clear()`)."""
        self.status = fields
        if fields.get('radio_stop'):
            self.radio_stopped = True

    def odometry(self, fields: dict[str, Any], demand: tuple[float, float], motor_on: bool,
                 now: float) -> None:
        """Run the encoder check: `demand` the rim speeds asked (m/s), `motor_on` the enable."""
        powered = self.status is None or self.status['state'] == 'ready'
        for i, side in enumerate(('left', 'right')):
            count = fields[f'{side}_distance']
            moved, self._counts[i] = count != self._counts[i], count
            if moved or not (motor_on and powered and abs(demand[i]) >= self.p.encoder_speed):
                self._silent_since[i] = None
            elif self._silent_since[i] is None:
                self._silent_since[i] = now
            elif now - self._silent_since[i] >= self.p.encoder_time and self.encoder == 'none':
                self.encoder = f'encoder_{side}'

    def clear(self) -> None:
        """Reload: forget a failed encoder (the check finds it again if it is still failed)."""
        self.encoder = 'none'
        self.radio_stopped = False
        self._silent_since = [None, None]
