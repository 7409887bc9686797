"""The executive's maintenance display (Baker 1983, 8.2.2, 7.2), ROS-free.

One status per sub-system: the last 16 bytes in (status record) and out (command record), hex and
decoded, the record rate, the age of the last good record, rejections by reason, and OK / WARN /
ERROR with the reason - the thesis's "level 2": name the sub-system at fault. The executive node
publishes it on /diagnostics; agv-diag shows it as a live table.
"""

from dataclasses import dataclass
from typing import Any

from agv_nodes.records.ports import RecordReader, RecordWriter

OK, WARN, ERROR = 0, 1, 2
SUBSYSTEMS = {  # name: (status record in, command record out)
    'navigation': ('navigation_status', 'navigation_command'),
    'traction': ('traction_status', 'traction_command'),
    'route': ('route_status', 'route_command'), 'load': ('load_status', 'load_command'),
    'communications': ('comms_status', 'comms_command'),
}


@dataclass
class SubsystemHealth:
    """One row of the display."""

    name: str
    level: int
    message: str
    values: dict[str, str]


def _decoded(fields: dict[str, Any] | None) -> str:
    return ', '.join(f'{k}={v}' for k, v in fields.items()) if fields else '-'


class HealthMonitor:
    """Keeps the rate state between updates and builds the display."""

    def __init__(self, status_timeout: float = 0.3, reject_window: float = 1.0) -> None:
        self.status_timeout = status_timeout
        self.reject_window = reject_window
        self._last: dict[str, tuple[float, int, int]] = {}  # name: (time, accepted, rejected)
        self._rates: dict[str, float] = {}
        self._recent_rejects: dict[str, int] = {}

    def update(self, now: float, readers: dict[str, RecordReader],
               writers: dict[str, RecordWriter], executive: Any) -> list[SubsystemHealth]:
        """Return the display now (call at a steady rate, e.g. 1-2 Hz)."""
        rows = []
        fault = getattr(executive, 'fault', None)
        for name, (in_record, out_record) in SUBSYSTEMS.items():
            reader, writer = readers.get(in_record), writers.get(out_record)
            row = self._row(now, name, reader, writer, fault)
            if (max_age := getattr(executive, 'max_age', {}).get(name)) is not None:
                row.values['max age while supervising (s)'] = f'{max_age:.3f}'
            rows.append(row)
        rows.append(self._executive_row(executive))
        return rows

    def _row(self, now: float, name: str, reader: RecordReader | None,
             writer: RecordWriter | None, fault: tuple[str, str] | None) -> SubsystemHealth:
        values: dict[str, str] = {}
        if writer is not None:
            values['out (hex)'] = writer.last_raw.hex().upper() if writer.last_raw else '-'
            values['out'] = _decoded(writer.last_fields)
        level, reasons = OK, []
        if reader is None:
            return SubsystemHealth(name, WARN, 'no status record', values)
        values['in (hex)'] = reader.raw.hex().upper() if reader.raw else '-'
        values['in'] = _decoded(reader.fields)
        t0, acc0, rej0 = self._last.get(name, (now, reader.accepted, reader.rejected))
        if now - t0 >= 0.5:
            self._rates[name] = (reader.accepted - acc0) / (now - t0)
            self._recent_rejects[name] = reader.rejected - rej0
            self._last[name] = (now, reader.accepted, reader.rejected)
        elif name not in self._last:
            self._last[name] = (now, reader.accepted, reader.rejected)
        rate = self._rates.get(name, 0.0)
        age = reader.age_s(round(now * 1e9))
        values['rate (Hz)'] = f'{rate:.1f}'
        values['age (s)'] = 'never' if age == float('inf') else f'{age:.3f}'
        values['rejected'] = str(reader.rejected)
        values['rejects by reason'] = ', '.join(f'{k}={v}' for k, v in
                                                sorted(reader.rejects.items())) or 'none'
        values['lost (counter gaps)'] = str(reader.lost)
        if reader.last_error:
            values['last rejection'] = reader.last_error
        if age == float('inf'):
            level, reasons = ERROR, ['no status record received']
        elif age > max(self.status_timeout, 3 * reader.schema.period_ms / 1000.0):
            # (communications reports every 100 ms: three periods, not the 50 ms statuses' 150)
            level, reasons = ERROR, [f'status record {age:.2f} s old (silent?)']
        fields = reader.fields or {}
        flags = {
            'traction': [('tripped', 'trip relay open: ' + str(fields.get('trip_cause'))),
                         ('radio_stop', 'radio stop'),
                         ('bumper', 'bumper pressed (another truck or an obstacle)')],
            'route': [('state', 'guide-wire pickup not yet heard' if fields.get('state') ==
                       'unheard' else 'guide wire lost')],
            'navigation': [('sensor_lost', 'marker sensor lost'),
                           ('input_fault', 'rejected a record')],
            'load': [('state', 'transfer failed: ' + str(fields.get('cause')))],
        }.get(name, [])
        for key, text in flags:
            value = fields.get(key)
            bad = value in ('lost', 'unheard') if (name, key) == ('route', 'state') else \
                value == 'failed' if (name, key) == ('load', 'state') else bool(value)
            if bad:
                # traction's start-up trip is its power-on state until the executive arms it
                # (00H then non-zero), a warning as in traction's own row, not a fault
                startup = (name, key) == ('traction', 'tripped') and \
                    fields.get('trip_cause') == 'startup'
                # a pickup not yet heard holds the truck (the executive fails the task if it
                # stays silent), a warning like the start-up trip
                unheard = (name, key) == ('route', 'state') and value == 'unheard'
                level = max(level, WARN if key == 'input_fault' or startup or unheard else ERROR)
                reasons.append(text)
        if recent := self._recent_rejects.get(name, 0):
            level = max(level, WARN)
            reasons.append(f'{recent} records rejected recently')
        if fault and fault[1] == name:
            level = ERROR
            reasons.insert(0, f'task failed: {fault[0].replace("_", " ")}')
        return SubsystemHealth(name, level, '; '.join(reasons) or 'OK', values)

    @staticmethod
    def _executive_row(executive: Any) -> SubsystemHealth:
        step = executive.step
        values = {'mode': executive.mode, 'task': str(executive.task_id),
                  'step': step.name if step else '-', 'report': executive.report['state'],
                  'pause': executive.pause}
        if executive.fault:
            cause, sub = executive.fault
            return SubsystemHealth('executive', ERROR, f'{cause.replace("_", " ")} ({sub})',
                                   values)
        paused = f'{executive.mode}, pause {executive.pause}' if executive.pause != 'none' \
            else executive.mode
        return SubsystemHealth('executive', OK, paused, values)
