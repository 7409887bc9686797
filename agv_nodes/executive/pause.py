"""The pause: the truck comes to rest and stays there, its task kept (a modern addition).

A mixin of ExecutiveCore (agv_nodes.executive.core). Baker 1983 has no pause: a task ran to its
end or was aborted. VDA 5050 2.1 has one (6.8.2, startPause: "No more AGV driving movements -
reaching next node is not necessary. Actions can continue. Order is resumable."), and the bridge
sends it as the task language's `pause` and `resume` (docs/tasks.md). Communications holds the
request and sends it in every comms_status (`paused`).

While it is asked, a non-zero drive demand becomes PAUSE_DEMAND, with executive priority so that
the Position link (navigation's positioning) cannot drive either. PAUSE_DEMAND lies within
traction's dead band: its closed loop ramps the speed to rest at its `max_decel` and `max_jerk`,
a controlled stop, where 00H would be the emergency stop (plug braking) and a fault. A demand of
00H (no task, a stop task's end, an abort, a fault) stays 00H. Everything else runs on: the
itinerary keeps its step, navigation counts the markers passed while the truck slows, a load or
a dwell goes on ("Actions can continue"), supervision stays. At resume the demand and the link
come back and the step carries on as if never paused: a positioning to the stop marker goes on
from where the truck rests.

The executive's word on it is comms_command `pause`: `stopping` until traction has reported no
more than `rest_speed` for `rest_time`, `paused` after, `none` when not asked, and `unable` on
the camera truck, whose motors route following drives (its executive sends no demand).
"""

from typing import Any

PAUSE_DEMAND = 1  # % armature duty: within traction's dead band, so its ramp's target is rest


class Pause:
    """The pause (see the module docstring)."""

    pause_asked = False  # comms_status paused
    pause = 'none'  # comms_command pause: none | stopping | paused | unable
    _rest_since = 0.0

    def _pause_record(self, fields: dict[str, Any], now: float) -> None:
        """Take comms_status's `paused`: the request holds until it is cleared."""
        asked = bool(fields.get('paused', 0))
        if asked != self.pause_asked:
            self.pause_asked = asked
            self._log(now, 'pause asked: the truck comes to rest' if asked else
                      'resume asked: the truck drives as its task asks')

    def _update_pause(self, now: float) -> None:
        """Set the word on the pause from the request and traction's speed."""
        if not self.pause_asked:
            word = 'none'
        elif self.camera:
            word = 'unable'
        else:
            speed = abs((self.status.get('traction') or {}).get('speed', 0))
            if self.pause == 'none' or speed > self.p.rest_speed:
                self._rest_since = now
            word = 'paused' if now - self._rest_since >= self.p.rest_time else 'stopping'
        if word != self.pause:
            self.pause = word
            self._log(now, f'pause: {word}')

    def pausing(self) -> bool:
        """Return True while the drive is held at rest by a pause."""
        return self.pause_asked and not self.camera

    def _paused_drive(self, demand: int, priority: int) -> tuple[int, int]:
        """Return traction's demand and executive priority as the pause leaves them."""
        if demand and self.pausing():
            return (PAUSE_DEMAND if demand > 0 else -PAUSE_DEMAND), 1
        return demand, priority
