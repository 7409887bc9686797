"""agv-fleet-sim's control channel: what a tester may ask of the running fleet, and its syntax.

The same commands come as JSON on the MQTT topic `<interface>/v2/<manufacturer>/fleet-sim/
control` and as lines on the simulator's standard input (docs/fleet_simulator.md):

    JSON                                                            line
    {"command": "fault", "serialNumber": "agv2", "fault": "drive"}  fault agv2 drive
    {"command": "fault", "serialNumber": "agv2", "fault": "blockedMarker", "marker": "A3.1"}
                                                                    fault agv2 blockedMarker A3.1
    {"command": "clear", "serialNumber": "agv2", "fault": "radioStop"}  clear agv2 radioStop
    {"command": "add", "serialNumber": "agv9", "start": "A2.1"}     add agv9 A2.1
    {"command": "remove", "serialNumber": "agv3"}                   remove agv3
    {"command": "status"}                                           status
    {"command": "quit"}                                             quit

A command that does not parse raises CommandError with one line saying what is wrong; the
simulator counts it, answers it on `fleet-sim/status` and acts on nothing of it.
"""

from __future__ import annotations

from dataclasses import dataclass
import json
from typing import Any

# The faults a tester may inject (agv_nodes.fleet.fleet_sim_faults says what each does).
FAULTS = ('drive', 'radioStop', 'blockedMarker', 'brokerLink')
VERBS = ('fault', 'clear', 'add', 'remove', 'status', 'quit')
SYNTAX = ('fault TRUCK drive|radioStop|brokerLink, fault TRUCK blockedMarker MARKER, '
          'clear TRUCK FAULT [MARKER], add TRUCK START_MARKER, remove TRUCK, status, quit')
_KEYS = {'command', 'serialNumber', 'fault', 'marker', 'start'}


class CommandError(ValueError):
    """A control command that cannot be taken; the message says why, in one line."""


@dataclass(frozen=True)
class Command:
    """One control command (see the module docstring)."""

    verb: str
    truck: str = ''
    fault: str = ''
    marker: str = ''  # blockedMarker's marker
    start: str = ''  # add's start marker

    def __str__(self) -> str:
        return ' '.join(w for w in (self.verb, self.truck, self.fault, self.marker, self.start)
                        if w)


def _checked(command: Command) -> Command:
    verb = command.verb
    if verb not in VERBS:
        raise CommandError(f'unknown command {verb!r}; commands: {SYNTAX}')
    if verb in ('status', 'quit'):
        if command.truck or command.fault or command.marker or command.start:
            raise CommandError(f'{verb} takes nothing more')
        return command
    if not command.truck:
        raise CommandError(f'{verb}: no truck named')
    if verb in ('fault', 'clear'):
        if command.fault not in FAULTS:
            raise CommandError(f'{verb} {command.truck}: fault {command.fault!r} is not one of '
                               f'{", ".join(FAULTS)}')
        if (command.fault == 'blockedMarker') != bool(command.marker):
            raise CommandError(f'{verb} {command.truck} {command.fault}: a marker goes with '
                               'blockedMarker and with nothing else')
        if command.start:
            raise CommandError(f'{verb}: a start marker goes with add only')
    elif verb == 'add':
        if not command.start or command.fault or command.marker:
            raise CommandError(f'add {command.truck}: give its start marker and nothing else')
    elif command.fault or command.marker or command.start:  # remove
        raise CommandError(f'remove {command.truck}: takes nothing more')
    return command


def from_line(line: str) -> Command:
    """Return the command of a line of standard input (SYNTAX)."""
    words = line.split()
    if not words:
        raise CommandError(f'empty; commands: {SYNTAX}')
    verb, rest = words[0], words[1:]
    if verb not in VERBS:
        raise CommandError(f'unknown command {verb!r}; commands: {SYNTAX}')
    fields: dict[str, str] = {}
    if verb in ('fault', 'clear') and len(rest) in (2, 3):
        fields = dict(zip(('truck', 'fault', 'marker'), rest, strict=False))
    elif verb == 'add' and len(rest) == 2:
        fields = {'truck': rest[0], 'start': rest[1]}
    elif verb == 'remove' and len(rest) == 1:
        fields = {'truck': rest[0]}
    elif verb not in ('status', 'quit') or rest:
        raise CommandError(f'{line.strip()!r}: expected one of {SYNTAX}')
    return _checked(Command(verb, **fields))


def from_json(payload: bytes | str) -> Command:
    """Return the command of a JSON control message (see the module docstring)."""
    try:
        doc: Any = json.loads(payload)
    except (ValueError, UnicodeDecodeError) as exc:
        raise CommandError(f'not JSON: {exc}') from None
    if not isinstance(doc, dict):
        raise CommandError('not a JSON object')
    if unknown := sorted(set(doc) - _KEYS):
        raise CommandError(f'unknown key {unknown[0]!r} (keys: {", ".join(sorted(_KEYS))})')
    if bad := sorted(k for k, v in doc.items() if not isinstance(v, str)):
        raise CommandError(f'{bad[0]!r} must be a string')
    return _checked(Command(doc.get('command', ''), doc.get('serialNumber', ''),
                            doc.get('fault', ''), doc.get('marker', ''), doc.get('start', '')))
