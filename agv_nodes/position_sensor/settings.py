"""Position sensor settings: every parameter of the node, its default and its meaning."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from agv_nodes.markers import THRESHOLDS
from agv_nodes.settings import setting


@dataclass
class SensorProcessing:
    """PC6/1's SAMPLE, THRESH and DECODE (thesis ch 5, App. B.1) and the modern decoders."""

    unit: str = setting('sensor1', 'Table 7.1 threshold set used where white or black is '
                        'empty', choices=tuple(THRESHOLDS))
    white: tuple[int, ...] = setting((), 'THRON per detector 1-8, x4 running-sum units (empty: '
                                     'Table 7.1 of unit)', lo=0, hi=1020, length=8)
    black: tuple[int, ...] = setting((), 'THROFF per detector 1-8, x4 running-sum units '
                                     '(empty: Table 7.1 of unit)', lo=0, hi=1020, length=8)
    min_consecutive_matches: int = setting(2, 'equal matches in successive snapshots before a '
                                           'recognition (thesis 7.1.4: 2; the printed '
                                           'listing: 1)', lo=1, hi=10)
    variant: str = setting('intended', "intended design, or the printed listing's defects "
                           '(black-test compare, EDGE search length 5)',
                           choices=('intended', 'as_listed'))
    # Thesis 5.2.2.2, fig 5.21: 4. A shorter filter smears a marker over fewer samples, so
    # fast passes give more matching snapshots (bench/recognition_bench.py).
    run_length: int = setting(4, 'running-sum filter length in snapshots; the thresholds stay '
                              "in the thesis's x4 units and scale by run_length / 4", lo=1,
                              hi=8)
    # A held code only extends a streak of matches: one snapshot of the streak must have every
    # detector decided (bench/recognition_bench.py).
    invalid_band: str = setting('invalid', 'a detector between its thresholds: invalid (thesis '
                                '5.2.3: no CODE that snapshot) or hold (a Schmitt trigger: it '
                                'keeps its last decision until it crosses the other threshold)',
                                choices=('invalid', 'hold'))
    # bench/recognition_bench.py: no miss and no misread in 10,020 passes across the tolerance
    # band at 1 and 2 m/s with `sequence`, where the thesis rule missed 974 and 4,528.
    decoder: str = setting('sequence', 'how the navigating table is read: sequence (each '
                           "detector column reads the passing card's elements in time, besides "
                           'the thesis rule) or snapshot (thesis 5.2.3 alone: one snapshot with '
                           'every detector decided, min_consecutive_matches times in a row)',
                           choices=('sequence', 'snapshot'))
    # Without the column-delay checks of sequence.py, 2 lets a truck stopping or changing
    # speed over a card misread it (3 times in 1,800 scripted passes, bench --motion); with
    # those checks neither 2, 3 nor 4 misread in 2,700, and 4 missed 1 of 10,020 passes at
    # 2 m/s where 3 missed none.
    sequence_agree: int = setting(3, 'detector columns (of 4) that must read the same card, '
                                  'none of the others reading another (sequence decoder)',
                                  lo=1, hi=4)
    # It reads each element at its middle, and a 20 mm element lasts 3.4 snapshots at 2 m/s,
    # so it wants less smear than THRESH's run_length 4 (10,020 passes at 2 m/s: 335 missed
    # with 4, none with 2 or 1).
    sequence_run_length: int = setting(2, "the sequence decoder's own running-sum length, "
                                       'snapshots', lo=1, hi=8)
    sequence_margin: float = setting(0.25, "band units an element's reading must keep from "
                                     'mid-band (sequence decoder)', lo=0.0, hi=0.49)
    heartbeat: float = setting(0.020, 'longest time between position_sensor_status records, s',
                               lo=0.005, hi=1.0)
    # 100 ms = 34 snapshots: a silent ADC is reported stale by the next 20 ms heartbeat and
    # navigation asks for speed 0 at once, inside the 200 ms the fault tests allow after any
    # node goes silent (the value the graph's fault tests were measured with).
    adc_timeout: float = setting(0.100, 'seconds without an ADC snapshot before adc_stale is '
                                 'reported', lo=0.005, hi=5.0)
    saturation: int = setting(255, 'a dark (IREDs off) reading at this ADC level means the '
                              'sensor is blinded (saturated)', lo=1, hi=255)

    def thresholds(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """(white, black) per detector: the settings, or Table 7.1 of `unit` where empty."""
        table = THRESHOLDS.get(self.unit, THRESHOLDS['sensor1'])
        return tuple(self.white) or table['white'], tuple(self.black) or table['black']

    def problems(self) -> list[tuple[str, Any, str]]:
        """Make the checks `build` needs beyond each field's own.

        Each black threshold must be below its white one.
        """
        white, black = self.thresholds()
        low = [d for d, (w, b) in enumerate(zip(white, black, strict=True), 1) if b >= w]
        if not low:
            return []
        name = 'black' if self.black or not self.white else 'white'
        return [(name, list(getattr(self, name)), 'each black threshold must be below its white '
                 f'one (detector {", ".join(map(str, low))}; empty = Table 7.1 of {self.unit})')]
