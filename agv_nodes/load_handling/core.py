"""Load handling: the truck's two roller conveyors (Baker 1983, 3.5.3, 6.3.2; fig 3.1 c, d, g, h).

A new `job` in load_command starts a transfer on the given conveyor: wait (up to `align_wait`)
until a workstation answers the ultrasonic link (the truck at rest and aligned), check there is a
load to take (load) or room for it (unload), run the conveyor with the station request until the
load-present sensor changes, and report done; otherwise report failed with the cause (timeout,
no_load, truck_moving, station_full). action = stop turns everything off at once.
"""

from __future__ import annotations

from typing import Any

from agv_nodes.load_handling.settings import LoadParams
from agv_nodes.subsystem import SubsystemCore


class LoadHandlingCore(SubsystemCore):
    """See the module docstring."""

    node, settings_type, period_setting = 'load_handling', LoadParams, 'period'

    def __init__(self, params: LoadParams | None = None) -> None:
        super().__init__(params)
        self.job = None  # the job number being (or last) handled
        self.action = 'idle'
        self.conveyor = 'first'
        self.state = 'idle'
        self.cause = 'none'
        self.phase = ''
        self.started = 0.0
        self.timeout = 20.0
        self.sensors: dict[str, int] = {'load_first': 0, 'load_second': 0,
                                        'station_aligned': 0, 'station_load': 0,
                                        'station_full': 0, 'transfer': 0}
        self.running = False

    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """load_command or conveyor_status."""
        if record == 'conveyor_status':
            self.sensors = fields
            return None
        if fields['action'] == 'stop':
            self.running = False
            if self.state == 'running':
                self.state, self.cause = 'failed', 'none'
            return self.tick(now)
        if fields['job'] != self.job and fields['action'] in ('load', 'unload'):
            self.job = fields['job']
            self.action, self.conveyor = fields['action'], fields['conveyor']
            self.timeout = float(fields['timeout'])
            self.state, self.cause, self.phase = 'running', 'none', 'align'
            self.started = now
            self.running = False
            return self.tick(now)
        return None

    def _fail(self, cause: str) -> None:
        self.state, self.cause, self.running = 'failed', cause, False

    def tick(self, now: float) -> dict:
        """Advance the transfer; publish the conveyor drive and the status."""
        s = self.sensors
        here = s['load_first'] if self.conveyor == 'first' else s['load_second']
        if self.state == 'running':
            if self.phase == 'align':
                if s['station_aligned']:
                    if self.action == 'load' and not s['station_load']:
                        self._fail('no_load')  # fig 3.1 (c): load A is not there
                    elif self.action == 'load' and here:
                        self._fail('station_full')  # our conveyor is already occupied
                    elif self.action == 'unload' and not here:
                        self._fail('no_load')
                    elif self.action == 'unload' and s['station_full']:
                        self._fail('station_full')  # fig 3.1 (g): C cannot accept
                    else:
                        self.phase, self.running = 'transfer', True
                elif now - self.started > self.p.align_wait:
                    self._fail('truck_moving')
            elif self.phase == 'transfer':
                if not s['station_aligned']:
                    self._fail('truck_moving')  # the truck moved away mid-transfer
                elif (self.action == 'load') == bool(here):
                    self.state, self.running = 'done', False
            if self.state == 'running' and now - self.started > self.timeout:
                self._fail('timeout')
        drive = self.action if self.running else 'off'
        command = {'first': drive if self.conveyor == 'first' else 'off',
                   'second': drive if self.conveyor == 'second' else 'off',
                   'station_request': int(self.running)}
        return {'conveyor_command': command,
                'load_status': {'state': self.state, 'cause': self.cause,
                                'load_first': s['load_first'], 'load_second': s['load_second'],
                                'job': self.job or 0}}
