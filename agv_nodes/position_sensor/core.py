"""The position sensor: PC6/1's SAMPLE, THRESH and DECODE on ADC snapshots (Baker ch 5, App B.1).

Per snapshot (Baker 1983, 5.2-5.3, 7.1.4):
1. d.c. removal: x = lit - dark, clamped at 0 (SUBT);
2. running sum of run length 4 per detector, TOTAL = x_k + ... + x_(k-3) (thresholds in x4 units),
   cleared on every table change (SAMIC/EDGIC): three snapshots after one read dark;
3. THRESH: WHITE if TOTAL > THRON, BLACK if TOTAL <= THROFF, otherwise the snapshot is INVALID;
4. CODE: each valid decision shifts a bit in, detector 1 ending in bit 7 (5.3.5.2);
5. TARGET: a valid CODE is looked up in the active table (navigating: UCTAB, the four location
   markers and the stop-marker centre; positioning: EDGE, the seven stop views);
6. a recognition is reported after `min_consecutive_matches` equal matches in a row (7.1.4; 1 = the
   printed listing).

`invalid_band = hold` (modern; default `invalid`): a detector inside its band keeps its last
decision, so a blurred card yields more matching snapshots; one snapshot of the streak must still
have every detector decided, which keeps held codes from misreading.

`decoder = sequence` (modern, the default; `snapshot` is the thesis rule): in the navigating table
each detector column reads the passing card in time (agv_nodes.position_sensor.sequence);
positioning (creep speed, each view's timing drives the stop) always uses the snapshot rule, whose
CODE and `invalid` the status record carries either way.

`variant = as_listed` keeps the listing's defects (5.2.3, App. B.1, register items 1 and 14): the
black test compares only the high bytes of TOTAL and THROFF, and EDGE is searched over LEN = 5
entries, so stop views 6 and 7 never match; `intended` (default) is the design as described.

Steps 1-4 and the sequence decoder's running sum may run in C, with the same results
(`kernels`; agv_nodes/position_sensor/kernels.py).
"""

from collections.abc import Sequence
from operator import itemgetter
from typing import Any

from agv_nodes.markers import DARK_FIELDS, LIT_FIELDS, LOCATION_TABLE, STOP_VIEWS
from agv_nodes.position_sensor import kernels
from agv_nodes.position_sensor.sequence import SequenceDecoder
from agv_nodes.position_sensor.settings import SensorProcessing
from agv_nodes.subsystem import SubsystemCore

_lit, _dark = itemgetter(*LIT_FIELDS), itemgetter(*DARK_FIELDS)  # a snapshot's 8 + 8 values


class PositionSensorCore(SubsystemCore):
    """Snapshots in, recognitions out; see the module docstring."""

    node, settings_type, period_setting = 'position_sensor', SensorProcessing, 'heartbeat'

    def __init__(self, params: SensorProcessing | None = None) -> None:
        super().__init__(params)
        kernel = kernels.select(self.p.kernels)  # None: the Python code below
        # its functions, not the module, which would not deep-copy (tests fork a truck)
        self._c_thresh = None if kernel is None else kernel.thresh
        self._c_levels = None if kernel is None else kernel.levels
        # THRESH's variants, fixed with the settings (asked 340 times a second)
        self._as_listed = self.p.variant == 'as_listed'
        self._hold = self.p.invalid_band == 'hold'
        self.white, self.black = self.p.thresholds()  # THRON, THROFF (x4 units)
        n = self.p.run_length
        self._white = [w * n // 4 for w in self.white]  # THRON in run_length units
        self._black = [b * n // 4 for b in self.black]  # THROFF
        self.table, self.epoch = 'navigating', 0
        self._oldest = [[0] * 8 for _ in range(self.p.run_length)]  # OLDEST rows
        self._total = [0] * 8  # TOTAL
        self._row = 0  # run counter
        self.code = 0  # CODE of the last valid snapshot
        self.invalid = self.saturated = False
        self.identity, self.stop_view = 0xFF, 0  # the last recognition, as reported
        self.recognitions = self.samples = self._streak = 0
        self._streak_key: int | None = None
        self._streak_decisive = False  # a snapshot of the streak had no detector in the band
        self._reported = False  # this streak has been reported
        self._held: list[int | None] = [None] * 8  # each detector's last WHITE/BLACK decision
        self._last_adc: float | None = None
        self._first_now: float | None = None  # the first time a status was made
        self._last_status: float | None = None  # sim time of the last status record
        self._templates = self._table()
        self._sequence = SequenceDecoder(self._templates, self.p.sequence_agree,
                                         self.p.sequence_margin)
        m = self.p.sequence_run_length / 4  # its thresholds, like THRESH's, scale by n/4
        self._seq_black = [b * m for b in self.black]
        self._seq_band = [max(1e-6, (w - b) * m) for w, b in zip(self.white, self.black,
                                                                  strict=True)]
        self._clear_sequence_sum()
        self._passage = -1  # the sequence decoder's passage the set below belongs to
        self._passage_found: set[int] = set()  # identities reported during it

    # -- tables -----------------------------------------------------------------------------
    def _table(self) -> dict[int, int]:
        """CODE -> identity (navigating) or view number (positioning), as TARGET searches."""
        if self.table == 'navigating':
            return {code: identity for code, identity in LOCATION_TABLE}
        # the listing's LEN = 5 over EDGE (Baker 1983, App. B.1)
        views = 5 if self.p.variant == 'as_listed' else 7
        return {code: view for view, (code, _speed, _mm) in enumerate(STOP_VIEWS[:views], 1)}

    def _reset_filter(self) -> None:
        """SAMIC / EDGIC: clear OLDEST, TOTAL and the counter; CODE := 0."""
        self._oldest = [[0] * 8 for _ in range(self.p.run_length)]
        self._total, self._row = [0] * 8, 0
        self._streak_key, self._streak = None, 0
        self._held = [None] * 8
        self._sequence.templates = self._templates
        self._sequence.reset()
        self._clear_sequence_sum()

    def _clear_sequence_sum(self) -> None:
        """Clear the sequence decoder's running sum, with THRESH's (SAMIC / EDGIC)."""
        self._seq_oldest = [[0] * 8 for _ in range(self.p.sequence_run_length)]
        self._seq_total, self._seq_row = [0] * 8, 0

    @property
    def _reads_sequence(self) -> bool:
        return self.p.decoder == 'sequence' and self.table == 'navigating'

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """adc_snapshot (340 Hz) or position_sensor_command (from navigation)."""
        if record == 'position_sensor_command':
            if fields['epoch'] != self.epoch or fields['table'] != self.table:
                self.epoch, self.table = fields['epoch'], fields['table']
                self._templates = self._table()
                self._reset_filter()
            return None
        self._last_adc = now
        return self.sample(_lit(fields), _dark(fields), now)

    def sample(self, lit: Sequence[int], dark: Sequence[int], now: float) -> dict | None:
        """One SAMPLE + DECODE; returns a status record when a recognition is made."""
        p = self.p
        self.samples = (self.samples + 1) & 0xFFFF
        self.saturated = max(dark) >= p.saturation
        row = self._oldest[self._row]
        if self._c_thresh is None:
            code, valid, decisive = self._thresh(lit, dark, row)
        else:
            code, valid, decisive = self._c_thresh(
                lit, dark, row, self._total, self._white, self._black, self._held,
                self._as_listed, self._hold)
        self._row = (self._row + 1) % p.run_length
        self.invalid = not valid
        # TARGET: most snapshots match nothing, which ends any streak (_snapshot_rule)
        if valid and code in self._templates:
            match = self._snapshot_rule(code, valid, decisive)
        else:
            match, self._streak_key, self._streak = None, None, 0
        if valid:
            self.code = code
        if not self._reads_sequence:
            return None if match is None else self._recognised(match, now)
        # The sequence decoder adds its reads of passing cards to the thesis rule's (which
        # still reads a card at rest or crawling); one report per card and passage.
        read = self._sequence.sample(self._sequence_levels(row))  # row: this x
        if self._sequence.passage != self._passage:
            self._passage, self._passage_found = self._sequence.passage, set()
        if match is None and read is not None:
            match, self.code = self._templates[read], read
        if match is None or match in self._passage_found:
            return None
        self._passage_found.add(match)
        return self._recognised(match, now)

    def _thresh(self, lit: Sequence[int], dark: Sequence[int],
                row: list[int]) -> tuple[int, bool, bool]:
        """SUBT, TOTAL and THRESH of one snapshot: (CODE, valid, decisive); `row` := its x."""
        code, valid, decisive = 0, True, True
        as_listed, hold, held = self._as_listed, self._hold, self._held
        totals, white, black = self._total, self._white, self._black
        for d in range(8):
            x = lit[d] - dark[d]
            if x < 0:  # SUBT clamp
                x = 0
            totals[d] = total = totals[d] + (x - row[d])
            row[d] = x
            if total > white[d]:
                code, held[d] = code << 1 | 1, 1
            elif (total >> 8 <= black[d] >> 8) if as_listed else (total <= black[d]):
                code, held[d] = code << 1, 0
            elif hold and (kept := held[d]) is not None:
                code = code << 1 | kept  # in the band: the detector's last decision
                decisive = False
            else:
                valid = False
        return code, valid, decisive

    def _snapshot_rule(self, code: int, valid: bool, decisive: bool) -> int | None:
        """TARGET and the consecutive-match count (thesis 7.1.4): a match to report, or None."""
        match = self._templates.get(code) if valid else None
        if match is None:
            self._streak_key, self._streak = None, 0
            return None
        if match == self._streak_key:
            self._streak += 1
        else:
            self._streak_key, self._streak, self._streak_decisive = match, 1, False
            self._reported = False
        # A held code only extends a streak: one snapshot of it must be decisive throughout
        # (with 'invalid', every counted snapshot is)
        self._streak_decisive = self._streak_decisive or decisive
        if self._reported or self._streak < self.p.min_consecutive_matches \
                or not self._streak_decisive:
            return None  # not yet, or already reported for this streak
        self._reported = True
        return match

    def _sequence_levels(self, x: list[int]) -> list[float]:
        """Sum SUBT's `x` over the sequence decoder's run, in band units (0 THROFF, 1 THRON)."""
        row, total = self._seq_oldest[self._seq_row], self._seq_total
        self._seq_row = (self._seq_row + 1) % self.p.sequence_run_length
        if self._c_levels is not None:
            return self._c_levels(x, row, total, self._seq_black, self._seq_band)
        for d in range(8):
            total[d] = total[d] + x[d] - row[d]
        row[:] = x
        return [(t - b) / band for t, b, band in zip(total, self._seq_black, self._seq_band,
                                                     strict=True)]

    def _recognised(self, match: int, now: float) -> dict[str, Any]:
        """Report a recognition: identity (navigating) or stop view (positioning) and status."""
        self.recognitions = (self.recognitions + 1) & 0xFF
        if self.table == 'navigating':
            self.identity, self.stop_view = match, 0
        else:
            self.identity, self.stop_view = 0xFF, match
        return {'position_sensor_status': self.status(recognised=True, now=now)}

    # -- outputs ----------------------------------------------------------------------------
    def status(self, recognised: bool = False, now: float = 0.0) -> dict[str, Any]:
        """Return the position_sensor_status record (restarts the heartbeat period)."""
        self._last_status = now
        if self._first_now is None:
            self._first_now = now
        # Stale: no snapshot for adc_timeout, from the first status if none came yet (else a
        # heartbeat before the first snapshot would call a healthy sensor stale at start-up).
        last = self._last_adc if self._last_adc is not None else self._first_now
        stale = now - last > self.p.adc_timeout
        return {
            'recognised': int(recognised), 'invalid': int(self.invalid), 'adc_stale': int(stale),
            'table': self.table, 'saturated': int(self.saturated), 'code': self.code,
            'identity': self.identity, 'stop_view': self.stop_view,
            'recognitions': self.recognitions, 'sample_count': self.samples, 'epoch': self.epoch,
        }

    def tick(self, now: float) -> dict | None:
        """Send the timer heartbeat, when no status went out for a heartbeat period."""
        if self._last_status is not None and now - self._last_status < self.p.heartbeat:
            return None
        return {'position_sensor_status': self.status(recognised=False, now=now)}
