"""The CONCIC-II's safety supervisor: the PAL state machine of Rajagopalan 1991, 6.3.11.

Hardware side of system 13. A programmable array logic chip (status LEDs X, Y, Z; port 0x28E)
holds the amplifiers' power relays, and the route code CO-n on its LEDs says why:

    state          thesis   route code  amplifiers
    reset          1        CO-0        off: after the hardware reset, LM628s reset, untested
    controllers_ok 2        CO-1        off: the LM628 read-back test passed (0x12 to 0x28E)
    ready          3        CO-2        on:  the encoder test passed, ready to operate
    fault          4        CO-5/6/7    off: DAC over-voltage (PAL bit 5), LM628 malfunction,
                                             watchdog timeout > 60 ms (PAL bit 7 -> 0)
    debug, undefined, bypass (5, 6, 7)  manual debugging, undefined fault, safety bypass: named
                                        in drive_status, never entered by the simulation

The E-stop de-energises every relay (PAL bit 0 low); the thesis gives it no route code, CO-4
here [A]. E-stop and watchdog stops need a hardware reset ("restart needs a hardware reset");
so does every fault state here, as state 4 is left only by a reset (or to manual debugging).
`hardware_reset()` is that reset: the latches clear and the start-up tests run again, so a
still-pressed E-stop or a still-injected fault trips again at once.

Start-up (6.3.11, required list items 1, 6, 7): reset -> controllers_ok after the LM628 test
(`self_test` s; an injected controller fault fails it: fault, CO-6), controllers_ok -> ready
after the encoder test (`self_test` s; an injected encoder fault fails it: the PAL stays in
controllers_ok with the failed side flagged). Departure: the thesis waits at CO-1 for the
green "motor power" button with the amber light flashing; the simulation presses it at once.

During motion the PAL sees the E-stop, the DAC (a commanded wheel speed beyond the full-speed
level, `max_wheel_speed`, the thesis's "DAC using more than 6 bits, > 4.2 V"), the LM628s (an
injected controller fault) and the computer watchdog, retriggered by each steering_command and
armed by the first one after a reset (before it the computer's loop has not started). An
encoder that stops counting during motion is for the software's check (route following's
drive_safety.py), as in the thesis ("Encoders Malfunctioning in Servo Loop #").
"""

from __future__ import annotations

from typing import Any

from agv_nodes.world.settings import Concic2Params

STATES = ('reset', 'controllers_ok', 'ready', 'fault', 'debug', 'undefined', 'bypass')
SIDES = ('none', 'left', 'right')
CODE_ESTOP, CODE_OVER_VOLTAGE, CODE_CONTROLLER, CODE_WATCHDOG = 4, 5, 6, 7
# Wheel speeds go out rounded to 1 mm/s: a command at the full-speed level itself is no
# over-voltage.
ROUNDING = 0.0005  # m/s


def encoder_reading(fault: str, left: float, right: float) -> tuple[float, float]:
    """Wheel speeds as the encoders report them: a failed encoder counts nothing."""
    return (0.0 if fault == 'left' else left), (0.0 if fault == 'right' else right)


class SafetyPal:
    """See the module docstring; the world steps it once per sample."""

    def __init__(self, params: Concic2Params) -> None:
        self.p = params
        self.records = 0  # drive_status records sent (the record carries the low byte)
        self.hardware_reset(0.0)

    def hardware_reset(self, now: float) -> None:
        """Press the reset button: latches cleared, the start-up tests run again from reset."""
        self.state, self.code, self.since = 'reset', 0, now
        self.estop = self.watchdog = self.over_voltage = False
        self.controller = self.encoder = 'none'
        self._retriggered: float | None = None  # the watchdog is armed by the first retrigger

    @property
    def powered(self) -> bool:
        """The amplifiers have power (only in state ready)."""
        return self.state == 'ready'

    def command(self, fields: dict[str, Any], now: float) -> None:
        """Take a steering_command: it retriggers the watchdog; over range it trips the DAC."""
        self._retriggered = now
        if fields['mode'] == 'wheel_speeds' and fields['enable']:
            top = max(abs(fields['left_speed']), abs(fields['right_speed'])) / 1000.0
            if top > self.p.max_wheel_speed + ROUNDING and self.state != 'fault':
                self.over_voltage = True
                self._trip(CODE_OVER_VOLTAGE, now)

    def step(self, now: float) -> None:
        """One sample: the fault inputs first, then the start-up sequence."""
        p = self.p
        if p.estop and not self.estop:  # the E-stop latches whatever state the PAL is in
            self.estop = True
            self._trip(CODE_ESTOP, now)
        if self.state == 'fault':
            return
        if p.controller_fault != 'none' and self.state != 'reset':
            self.controller = p.controller_fault
            self._trip(CODE_CONTROLLER, now)
        elif self._retriggered is not None and now - self._retriggered > p.watchdog:
            self.watchdog = True
            self._trip(CODE_WATCHDOG, now)
        elif now - self.since >= p.self_test:
            if self.state == 'reset':
                if p.controller_fault != 'none':  # the read-back test fails: LM628 malfunction
                    self.controller = p.controller_fault
                    self._trip(CODE_CONTROLLER, now)
                else:
                    self.state, self.code, self.since = 'controllers_ok', 1, now
            elif self.state == 'controllers_ok' and self.encoder == 'none':
                if p.encoder_fault != 'none':  # no feedback from the small move
                    self.encoder = p.encoder_fault
                else:
                    self.state, self.code, self.since = 'ready', 2, now

    def _trip(self, code: int, now: float) -> None:
        if self.state != 'fault':  # the first fault names the route code
            self.state, self.code, self.since = 'fault', code, now

    def record(self, radio_stop: bool = False) -> dict[str, Any]:
        """Return the next drive_status record (the battery as the data-acquisition ADC has it).

        `radio_stop`: the radio receiver's stop input, which holds the amplifiers' power off
        outside the PAL (the world's wiring); reported so the software can name the stop.
        """
        self.records += 1
        return {'state': self.state, 'route_code': self.code, 'estop': int(self.estop),
                'radio_stop': int(radio_stop),
                'watchdog': int(self.watchdog), 'over_voltage': int(self.over_voltage),
                'controller_fault': self.controller, 'encoder_fault': self.encoder,
                'battery': int(min(max(round(self.p.battery_voltage * 10), 0), 0xFFFF)),
                'sample': self.records & 0xFF}
