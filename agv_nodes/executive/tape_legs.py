"""Tape legs of the camera truck: a task's junction script through route_command, ROS-free.

The CONCIC-II (Rajagopalan 1991) follows floor tape by camera; a tape task is one leg along the
tape from where the truck stands and, with `then reverse`, a second leg back along the same tape
with the rear camera leading. Each leg gets a new `leg` counter value in route_command, so route
following counts its junctions and distance from 0.

Junctions (App. F.6-F.7): route following counts road signs as it sights them, from 0 on each
leg; while it has met k, the executive offers the decision for junction k + 1 of the leg (the
script's line for it, or the task's `unscripted` choice), numbered, with the line's wait. The
script numbers the task's junctions in the order its legs meet them, as the thesis's script
file numbered a run's (App. F.7, Fig. 6.32): the reverse leg's first junction is the one after
the last the forward leg met (a task's four script lines then serve both legs, and one number
means one junction). So a script applies in reverse too, left and right being those of the
direction of travel; a junction neither the script nor `unscripted` decides goes straight on.
A random decision is drawn as the thesis drew it: an even number turns, an odd one goes
straight; a turn draws again, even left and odd right (the thesis seeded with the time of day;
here `junction_seed`, so runs repeat). The task's camera_law goes with the forward leg (the
feedback law steers in reverse).

A reckon task is one dead-reckoning leg (App. F.9): route_command mode dead_reckoning with the
task's trajectory; route following drives along it by odometry alone and the leg ends, as a tape
leg with a length does, when its distance reaches the length.

A leg with a length goes to route following in route_command `length` (dm): it slows to the
thesis's parking speed near the end and cuts the motors so that the coast ends at the length
(Rajagopalan 1991, 7.3.4; camera_mode.py). Once route following reports it parked (state
idle) or its distance (cm) reaches the length, route_command goes idle (motors off: the thesis's
motor-off stop, from cruise if route following does not park) and the leg is done once the
distance has stood still for `leg_rest_time`.
A leg without one ends where the tape ends: route following reports no_track (no track in
absent_frames frames, motors off). no_track before a leg's length is a lost tape; no_branch
(the decision is not on the sign) and lost (a turn that did not finish) fail the task.
"""

from dataclasses import dataclass, field
import random
from typing import Any

from agv_nodes.communications.report_line import no_branch_text

SCRIPT_JUNCTIONS = 4  # comms_status junction_1..junction_4


@dataclass
class LegOutcome:
    """What a pass of a leg came to: running, done, or failed with a cause and a detail."""

    state: str  # running | done | failed
    cause: str = 'none'
    detail: str = ''
    report: dict[str, Any] = field(default_factory=dict)  # comms_command's fields of a failure


# comms_command's account of a no_branch, and its values for every other report
NO_BRANCH_FIELDS = {'junction': 0, 'sign_left': 0, 'sign_right': 0, 'sign_straight': 0,
                    'decision': 'none'}


def no_branch_fields(status: dict[str, Any], decision: str, number: int) -> dict[str, Any]:
    """Return comms_command's account of a no_branch: the junction, the sign's flags, decision.

    `number`: the junction's number in the task's script.
    """
    return {'junction': min(number, 255),
            'decision': decision if decision in ('left', 'right', 'straight') else 'none',
            **{f'sign_{way}': int(status.get(f'sign_{way}', 0))
               for way in ('left', 'right', 'straight')}}


def no_branch_detail(fields: dict[str, Any]) -> str:
    """Return the line no_branch_fields' account reads as (communications reports the same)."""
    return no_branch_text(fields['junction'], tuple(
        fields[f'sign_{way}'] for way in ('left', 'right', 'straight')), fields['decision'])


class TapeLegs:
    """See the module docstring: the legs of one tape task after another."""

    def __init__(self, seed: int, rest_time: float) -> None:
        self.rng = random.Random(seed)
        self.rest_time = rest_time
        self.leg = 0  # the route_command leg counter (0 = none yet)
        self.task: dict[str, Any] = {}
        self.length_cm = 0  # 0 = to the tape's end
        self.next_junction = 1  # of the leg (route following's count + 1)
        self.before = 0  # junctions the task's earlier legs met: the script's numbers go on
        self.met = 0  # junctions this leg has met (route_status)
        self.decision = ('straight', 0)
        self.decisions: dict[int, str] = {}  # the leg's junction -> the decision offered for it
        self.phase = ''  # driving | stopping
        self._still: tuple[int, float] | None = None  # (distance, since) while stopping
        self.obstacle = False  # route following holds the leg for an obstacle (its sonar)
        self.log: list[str] = []

    def start(self, task: dict[str, Any], kind: str, length_dm: int,
              route: dict[str, Any]) -> dict[str, Any]:
        """Begin a leg (tape, tape_reverse or reckon); return the route_command that starts it."""
        reverse = kind == 'tape_reverse'
        # The reverse leg numbers its junctions on from the forward leg's (the module docstring).
        self.before = self.before + self.met if reverse else 0
        self.task, self.met = task, 0
        self.leg = (self.leg + 1) & 0xFF or 1
        self.length_cm, self.next_junction, self.phase = length_dm * 10, 1, 'driving'
        self._still, self.decisions = None, {}
        self.decision = self._decide(1)
        route = {**route, 'camera_law': 'default' if reverse else task.get('camera_law',
                                                                            'default'),
                 'trajectory': int(task.get('trajectory', 0)) if kind == 'reckon' else 0,
                 'length': length_dm,
                 'camera': task.get('reverse_camera' if reverse else 'camera', 'default')}
        return self._command(route, 'dead_reckoning' if kind == 'reckon' else 'camera',
                             'reverse' if reverse else 'forward')

    def _decide(self, k: int) -> tuple[str, int]:
        """Return the decision and wait for the leg's junction k (the task's before + k)."""
        n = self.before + k
        if n <= SCRIPT_JUNCTIONS:
            decision = self.task.get(f'junction_{n}', 'straight')
            wait = self.task.get(f'wait_{n}', 0)
        else:
            decision, wait = self.task.get('unscripted', 'straight'), 0
        if decision == 'random':
            turn = self.rng.randrange(1 << 15) % 2 == 0
            decision = ('left' if self.rng.randrange(1 << 15) % 2 == 0 else 'right') \
                if turn else 'straight'
            self.log.append(f'junction {n}: random choice {decision}')
        self.decisions[k] = decision
        return decision, int(wait)

    def _command(self, route: dict[str, Any], mode: str, direction: str) -> dict[str, Any]:
        return {**route, 'mode': mode, 'direction': direction, 'junction': self.decision[0],
                'junction_number': self.next_junction, 'junction_wait': self.decision[1],
                'leg': self.leg}

    def no_branch(self, status: dict[str, Any]) -> dict[str, Any]:
        """Return a no_branch's account: the junction, the sign seen, its branches, decision."""
        met = int(status.get('junctions', 0))
        return no_branch_fields(status, self.decisions.get(met, self.decision[0]),
                                self.before + met)

    def update(self, status: dict[str, Any], route: dict[str, Any],
               now: float) -> tuple[LegOutcome, dict[str, Any]]:
        """Take route following's latest status; return the outcome and the route_command."""
        if status.get('leg') != self.leg:
            return LegOutcome('running'), route  # route following has not begun this leg yet
        state, distance = status.get('state'), int(status.get('distance', 0))
        if (state == 'obstacle') != self.obstacle:  # the sonar's stop and resume, reported
            self.obstacle = state == 'obstacle'
            self.log.append(f'leg {self.leg}: ' + (
                f'Obstacle detected after {distance / 100:.2f} m: stopped until it is removed'
                if self.obstacle else f'obstacle removed after {distance / 100:.2f} m: going on'))
        if state == 'no_branch':
            account = self.no_branch(status)
            return LegOutcome('failed', 'no_branch', no_branch_detail(account), account), route
        if state == 'lost':
            return LegOutcome('failed', 'lost_track', 'a junction turn did not finish'), route
        met = self.met = max(self.met, int(status.get('junctions', 0)))
        if self.phase == 'driving':
            if met >= self.next_junction:
                self.log.append(f'junction {self.before + met} met ({self.decision[0]})')
                self.next_junction = met + 1
                self.decision = self._decide(self.next_junction)
                route = self._command(route, route['mode'], route['direction'])
            if state == 'no_track':
                if self.length_cm and distance < self.length_cm:
                    return LegOutcome('failed', 'lost_track',
                                      f'no track after {distance / 100:.2f} m of '
                                      f'{self.length_cm / 100:.1f}'), route
                self.phase = 'stopping'  # the tape's end: route following cut the motors
            elif self.length_cm and (distance >= self.length_cm or state == 'idle'):
                # Route following parked (idle) at the length, or the distance reached it:
                # motors off (a motor-off stop from cruise when it does not park, 7.3.4).
                self.phase = 'stopping'
                route = {**route, 'mode': 'idle'}
            if self.phase == 'stopping':
                self.log.append(f'leg {self.leg}: stopping after {distance / 100:.2f} m')
        if self.phase == 'stopping':
            if self._still is None or self._still[0] != distance:
                self._still = (distance, now)
            elif now - self._still[1] >= self.rest_time:
                return LegOutcome('done'), route
        return LegOutcome('running'), route
