"""The position sensor: PC6/1's SAMPLE, THRESH and DECODE on ADC snapshots (Baker ch 5, App B.1).

Per snapshot (spec 2.2-2.7):
1. d.c. removal: x = lit - dark, clamped at 0 (SUBT);
2. running-sum filter of run length 4 per detector, TOTAL = x_k + ... + x_(k-3) (no division;
   thresholds are in x4 units), cleared on every table change (SAMIC/EDGIC), so the first three
   snapshots after a change read dark;
3. THRESH per detector: WHITE if TOTAL > THRON, BLACK if TOTAL <= THROFF, otherwise the
   snapshot is INVALID (all eight are still processed);
4. CODE: each valid decision shifts a bit in, detector 1 ending in bit 7 (spec 2.5);
5. TARGET: a valid CODE is looked up in the active table (navigating: UCTAB, the four location
   markers and the stop-marker centre; positioning: EDGE, the seven stop views);
6. a recognition is reported only after `min_consecutive_matches` equal matches in successive
   snapshots (thesis 7.1.4; 1 = the printed listing). An invalid or different snapshot resets
   the count.

`invalid_band = hold` (a modern option, default `invalid`): a detector inside its band keeps its
last decision instead of invalidating the snapshot, so a blurred card (standoff off focus, fast
passes) yields more matching snapshots; a recognition still needs one snapshot of the streak
with every detector decided, which keeps the held codes from making misreads.

`decoder = sequence` (a modern option, the default; `snapshot` is the thesis's rule above): in
the navigating table each detector column reads the passing card's four elements in time
(`sequence.SequenceDecoder`), so no single snapshot needs all eight detectors decided at once;
the positioning table (stop views at creep speed, each view's timing drives the stop) always
uses the snapshot rule. The snapshot CODE and `invalid` are still worked out for the status
record either way.

`variant = as_listed` keeps the listing's defects (spec 2.4, 2.6, register items 1 and 14): the
black test compares only the high bytes of TOTAL and THROFF, and the EDGE search covers LEN = 5
entries, so stop views 6 and 7 never match. The default `intended` is the design as described.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from agv_nodes.markers import DARK_FIELDS, LIT_FIELDS, LOCATION_TABLE, STOP_VIEWS, THRESHOLDS
from agv_nodes.position_sensor.sequence import SequenceDecoder


@dataclass
class SensorProcessing:
    """Position sensor settings (node parameters map onto these)."""

    white: tuple[int, ...] = THRESHOLDS['sensor1']['white']  # THRON, x4 units
    black: tuple[int, ...] = THRESHOLDS['sensor1']['black']  # THROFF
    min_consecutive_matches: int = 2  # thesis 7.1.4 (the printed listing: 1)
    variant: str = 'intended'  # or 'as_listed'
    # Running-sum filter length (thesis 5.2.2.2, fig 5.21: 4). The thresholds stay in the
    # thesis's x4 units and are scaled by run_length / 4; a shorter filter smears a marker over
    # fewer samples, so fast passes give more matching snapshots (bench/recognition_bench.py).
    run_length: int = 4
    # A detector between its thresholds: 'invalid' (thesis 5.2.3, spec 2.4: no CODE this
    # snapshot) or 'hold' (a Schmitt trigger: it keeps its last WHITE/BLACK decision until it
    # crosses the other threshold). A held code only extends a streak of matches: one snapshot
    # of the streak must have every detector decided (bench/recognition_bench.py).
    invalid_band: str = 'invalid'
    # How the navigating table is read: 'sequence' (modern, default: each column reads the
    # passing card's elements in time; bench/recognition_bench.py: no miss and no misread in
    # 10,020 passes across the tolerance band at 1 and 2 m/s, where the thesis rule missed
    # 974 and 4,528) or 'snapshot' (thesis 5.2.3: one snapshot with every detector decided,
    # min_consecutive_matches times in a row).
    decoder: str = 'sequence'
    # Columns that must read the same card, of 4 (none of the others may read it otherwise).
    # With 2, before the column-delay checks of sequence.py, a truck stopping or changing
    # speed over a card misread it 3 times in 1,800 scripted passes (bench --motion); with
    # those checks neither 2, 3 nor 4 misread in 2,700, and 4 missed 1 of 10,020 passes at
    # 2 m/s where 3 missed none.
    sequence_agree: int = 3
    # The sequence decoder's own running sum, snapshots: it reads each element at its middle,
    # and a 20 mm element lasts 3.4 snapshots at 2 m/s, so it wants less smear than THRESH's
    # run_length 4 (10,020 passes at 2 m/s: 335 missed with 4, none with 2 or 1).
    sequence_run_length: int = 2
    sequence_margin: float = 0.25  # band units an element's reading must keep from mid-band
    heartbeat: float = 0.020  # s between heartbeat status records
    # While snapshots arrive the heartbeat is counted in snapshots (6 at 340 Hz = 17.6 ms, just
    # inside the 20 ms period so the timer stays quiet), so its sample_count keeps reaching the
    # world even when a paced world has stopped the clock to let this node catch up
    # (world/pacing.py); the timer covers a silent ADC.
    heartbeat_samples: int = 6
    adc_timeout: float = 0.050  # s without a snapshot -> adc_stale
    saturation: int = 255  # a dark reading at this level means the sensor is blinded
    extra: dict = field(default_factory=dict)

    def check(self) -> list[tuple[str, Any, str]]:
        """Problems as (name, value, reason)."""
        bad = []
        for name in ('white', 'black'):
            values = getattr(self, name)
            if len(values) != 8 or not all(0 <= v <= 1020 for v in values):
                bad.append((f'{name}_thresholds', list(values), 'needs 8 values in 0..1020'))
        if len(self.white) == 8 and len(self.black) == 8 and any(
                b >= w for w, b in zip(self.white, self.black, strict=True)):
            bad.append(('black_thresholds', list(self.black), 'each must be below its white '
                        'threshold'))
        if self.variant not in ('intended', 'as_listed'):
            bad.append(('variant', self.variant, 'not intended or as_listed'))
        if self.invalid_band not in ('invalid', 'hold'):
            bad.append(('invalid_band', self.invalid_band, 'not invalid or hold'))
        if self.decoder not in ('sequence', 'snapshot'):
            bad.append(('decoder', self.decoder, 'not sequence or snapshot'))
        if not 1 <= self.sequence_agree <= 4:
            bad.append(('sequence_agree', self.sequence_agree, 'outside 1..4'))
        if not 0.0 <= self.sequence_margin < 0.5:
            bad.append(('sequence_margin', self.sequence_margin, 'outside 0..0.5'))
        if not 1 <= self.sequence_run_length <= 8:
            bad.append(('sequence_run_length', self.sequence_run_length, 'outside 1..8'))
        if not 1 <= self.run_length <= 8:
            bad.append(('run_length', self.run_length, 'outside 1..8'))
        if not 1 <= self.min_consecutive_matches <= 10:
            bad.append(('min_consecutive_matches', self.min_consecutive_matches, 'outside 1..10'))
        return bad


class PositionSensorCore:
    """Snapshots in, recognitions out; see the module docstring."""

    node = 'position_sensor'

    def __init__(self, params: SensorProcessing | None = None) -> None:
        self.p = params or SensorProcessing()
        self.period = self.p.heartbeat
        n = self.p.run_length
        self._white = [w * n // 4 for w in self.p.white]  # THRON in run_length units
        self._black = [b * n // 4 for b in self.p.black]  # THROFF
        self.table = 'navigating'
        self.epoch = 0
        self._oldest = [[0] * 8 for _ in range(self.p.run_length)]  # OLDEST rows
        self._total = [0] * 8  # TOTAL
        self._row = 0  # run counter
        self.code = 0  # CODE of the last valid snapshot
        self.invalid = False
        self.saturated = False
        self.identity = 0xFF
        self.stop_view = 0
        self.recognitions = 0
        self.samples = 0
        self._streak_key: int | None = None
        self._streak = 0
        self._streak_decisive = False  # a snapshot of the streak had no detector in the band
        self._reported = False  # this streak has been reported
        self._held: list[int | None] = [None] * 8  # each detector's last WHITE/BLACK decision
        self._last_adc: float | None = None
        self._first_now: float | None = None  # the first time a status was made
        self._last_status: float | None = None  # sim time of the last status record
        self._since_status = 0  # snapshots since the last status record
        self._templates = self._table()
        self._sequence = SequenceDecoder(self._templates, self.p.sequence_agree,
                                         self.p.sequence_margin)
        m = self.p.sequence_run_length / 4  # its thresholds, like THRESH's, scale by n/4
        self._seq_black = [b * m for b in self.p.black]
        self._seq_band = [max(1e-6, (w - b) * m) for w, b in zip(self.p.white, self.p.black,
                                                                  strict=True)]
        self._clear_sequence_sum()
        self._passage = -1  # the sequence decoder's passage the set below belongs to
        self._passage_found: set[int] = set()  # identities reported during it

    # -- tables -----------------------------------------------------------------------------
    def _table(self) -> dict[int, int]:
        """CODE -> identity (navigating) or view number (positioning), as TARGET searches."""
        if self.table == 'navigating':
            return {code: identity for code, identity in LOCATION_TABLE}
        views = 5 if self.p.variant == 'as_listed' else 7  # LEN = 5 over EDGE (spec 2.6)
        return {code: view for view, (code, _speed, _mm) in enumerate(STOP_VIEWS[:views], 1)}

    def _reset_filter(self) -> None:
        """SAMIC / EDGIC: clear OLDEST, TOTAL and the counter; CODE := 0."""
        self._oldest = [[0] * 8 for _ in range(self.p.run_length)]
        self._total = [0] * 8
        self._row = 0
        self._streak_key, self._streak = None, 0
        self._held = [None] * 8
        self._sequence.templates = self._templates
        self._sequence.reset()
        self._clear_sequence_sum()

    def _clear_sequence_sum(self) -> None:
        """The sequence decoder's running sum, cleared with THRESH's (SAMIC / EDGIC)."""
        self._seq_oldest = [[0] * 8 for _ in range(self.p.sequence_run_length)]
        self._seq_total = [0] * 8
        self._seq_row = 0

    @property
    def _reads_sequence(self) -> bool:
        return self.p.decoder == 'sequence' and self.table == 'navigating'

    # -- inputs -----------------------------------------------------------------------------
    def on_record(self, record: str, fields: dict[str, Any], now: float) -> dict | None:
        """adc_snapshot (340 Hz) or position_sensor_command (from navigation)."""
        if record == 'position_sensor_command':
            if fields['epoch'] != self.epoch or fields['table'] != self.table:
                self.epoch = fields['epoch']
                self.table = fields['table']
                self._templates = self._table()
                self._reset_filter()
            return None
        lit = [fields[k] for k in LIT_FIELDS]
        dark = [fields[k] for k in DARK_FIELDS]
        self._last_adc = now
        self._since_status += 1
        out = self.sample(lit, dark, now)
        if out is None and self._since_status >= self.p.heartbeat_samples:
            out = {'position_sensor_status': self.status(recognised=False, now=now)}
        return out

    def sample(self, lit: list[int], dark: list[int], now: float) -> dict | None:
        """One SAMPLE + DECODE; returns a status record when a recognition is made."""
        p = self.p
        self.samples = (self.samples + 1) & 0xFFFF
        self.saturated = max(dark) >= p.saturation
        row = self._oldest[self._row]
        code, valid, decisive = 0, True, True
        as_listed = p.variant == 'as_listed'
        hold, held = p.invalid_band == 'hold', self._held
        for d in range(8):
            x = lit[d] - dark[d]
            if x < 0:
                x = 0  # SUBT clamp
            self._total[d] += x - row[d]
            row[d] = x
            total = self._total[d]
            if total > self._white[d]:
                code = code << 1 | 1
                held[d] = 1
            elif (total >> 8 <= self._black[d] >> 8) if as_listed else (total <= self._black[d]):
                code <<= 1
                held[d] = 0
            elif hold and held[d] is not None:
                code = code << 1 | held[d]  # in the band: the detector's last decision
                decisive = False
            else:
                valid = False
        self._row = (self._row + 1) % p.run_length
        self.invalid = not valid
        match = self._snapshot_rule(code, valid, decisive)
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
            match = self._templates[read]
            self.code = read
        if match is None or match in self._passage_found:
            return None
        self._passage_found.add(match)
        return self._recognised(match, now)

    def _snapshot_rule(self, code: int, valid: bool, decisive: bool) -> int | None:
        """TARGET and the consecutive-match count (thesis 7.1.4): a match to report, or None."""
        p = self.p
        if not valid:
            self._streak_key, self._streak = None, 0
            return None
        match = self._templates.get(code)
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
        if self._reported or self._streak < p.min_consecutive_matches \
                or not self._streak_decisive:
            return None  # not yet, or already reported for this streak
        self._reported = True
        return match

    def _sequence_levels(self, x: list[int]) -> list[float]:
        """The sequence decoder's running sum of this snapshot's d.c.-removed `x` (as SUBT
        made it for THRESH), in band units (0 = THROFF, 1 = THRON)."""
        row, total = self._seq_oldest[self._seq_row], self._seq_total
        self._seq_row = (self._seq_row + 1) % self.p.sequence_run_length
        z = []
        for d in range(8):
            t = total[d] + x[d] - row[d]
            total[d], row[d] = t, x[d]
            z.append((t - self._seq_black[d]) / self._seq_band[d])
        return z

    def _recognised(self, match: int, now: float) -> dict[str, Any]:
        """A recognition: identity (navigating) or stop view (positioning) and its status."""
        self.recognitions = (self.recognitions + 1) & 0xFF
        if self.table == 'navigating':
            self.identity, self.stop_view = match, 0
        else:
            self.identity, self.stop_view = 0xFF, match
        return {'position_sensor_status': self.status(recognised=True, now=now)}

    # -- outputs ----------------------------------------------------------------------------
    def status(self, recognised: bool = False, now: float = 0.0) -> dict[str, Any]:
        """The position_sensor_status record (restarts the heartbeat count)."""
        self._last_status, self._since_status = now, 0
        if self._first_now is None:
            self._first_now = now
        # Stale: no snapshot for adc_timeout - counted from the first time this node kept
        # time when none has come yet (a heartbeat due before the first snapshot of a run
        # had called a healthy sensor stale, and navigation LOST, at every start-up).
        last = self._last_adc if self._last_adc is not None else self._first_now
        stale = now - last > self.p.adc_timeout
        return {
            'recognised': int(recognised),
            'invalid': int(self.invalid),
            'adc_stale': int(stale),
            'table': self.table,
            'saturated': int(self.saturated),
            'code': self.code,
            'identity': self.identity,
            'stop_view': self.stop_view,
            'recognitions': self.recognitions,
            'sample_count': self.samples,
            'epoch': self.epoch,
        }

    def tick(self, now: float) -> dict | None:
        """The timer heartbeat, when no status went out for a heartbeat period."""
        if self._last_status is not None and now - self._last_status < self.p.heartbeat:
            return None
        return {'position_sensor_status': self.status(recognised=False, now=now)}
