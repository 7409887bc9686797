"""The itinerary: a task record into steps (Baker 1983, fig 3.1, level 2), ROS-free.

A tape task (the camera truck, Rajagopalan 1991, App. F.6-F.7) is one or two legs: tape, then
tape_reverse with `then reverse`; a reckon task (App. F.9) one leg, reckon
(agv_nodes.executive.tape_legs runs them). A manual task (App. F.4) is one step, manual, for its
dwell (0: until an abort); a calibrate task (App. F.3) one step, calibrate (value 1: the rear
camera).
"""

from dataclasses import dataclass
from typing import Any

NO_TASK = 0xFF


@dataclass
class Step:
    """One itinerary step."""

    kind: str
    location: int = NO_TASK
    edge: int = 0
    value: int = 0  # seconds, SRM angle, conveyor index
    name: str = ''


def itinerary(task: dict[str, Any]) -> list[Step]:
    """Fig 3.1 level 2: the steps of one task record (empty = nothing to do / bad task)."""
    op, n = task['op'], task['location']
    edge = 1 if task['marker'] == 'second' else 0
    conveyor = 1 if task['conveyor'] == 'second' else 0
    steps: list[Step] = []
    if op in ('stop', 'load', 'unload', 'wait'):
        steps.append(Step('goto', n, edge, name=f'go to L{n}, stop marker {edge + 1}'))
        if op == 'stop' and task['marker'] == 'first_then_second':
            steps.append(Step('next_marker', n, 1, name=f'advance to the 2nd stop marker at L{n}'))
        elif op in ('load', 'unload'):
            steps.append(Step(op, n, value=conveyor, name=f'{op} on conveyor {conveyor + 1}'))
        elif op == 'wait':
            steps.append(Step('wait', n, value=task['dwell'], name=f'wait {task["dwell"]} s'))
    elif op == 'pass':
        steps.append(Step('pass', n, name=f'pass L{n} without stopping'))
    elif op == 'srm':
        steps.append(Step('srm', n, value=task['srm_angle'],
                          name=f'SRM at L{n}, {task["srm_angle"]} deg'))
    elif op == 'tape':
        length = task['leg_distance']
        steps.append(Step('tape', value=length, name='tape leg forward, ' + (
            f'{length / 10:.1f} m' if length else 'to the end of the tape')))
        if task['then'] == 'reverse':
            back = task['reverse_distance']
            steps.append(Step('tape_reverse', value=back, name='tape leg in reverse, ' + (
                f'{back / 10:.1f} m' if back else 'to the end of the tape')))
        return steps
    elif op == 'reckon':
        if not task['leg_distance']:
            return []  # only the distance ends a dead-reckoning leg
        trajectory = task['trajectory']
        along = f'stored trajectory {trajectory}' if trajectory else 'the identified track'
        return [Step('reckon', value=task['leg_distance'],
                     name=f'dead reckoning along {along}, {task["leg_distance"] / 10:.1f} m')]
    elif op == 'manual':
        return [Step('manual', value=task['dwell'], name='manual driving from cmd_vel, ' + (
            f'{task["dwell"]} s' if task['dwell'] else 'until an abort'))]
    elif op == 'calibrate':
        rear = task['then'] == 'reverse'
        return [Step('calibrate', value=int(rear),
                     name=f'calibrate the {"rear" if rear else "front"} camera')]
    elif op == 'transfer':
        b, c = n, task['destination']
        steps += [Step('goto', b, 0, name=f'go to B = L{b}'),
                  Step('load', b, value=0, name='check A is there, load A'),
                  Step('goto', c, 0, name=f'go to C = L{c}'),
                  Step('unload', c, value=0, name='check C can accept, unload A')]
    if steps and task['then'] == 'continue':
        steps.append(Step('continue', name='carry on along the wire'))
    return steps
