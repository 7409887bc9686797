"""position_sensor: marker recognition from ADC snapshots (ros2 run agv_nodes position_sensor).

Reads hw/position_sensor/adc (340 Hz, best effort) and position_sensor/command; writes
position_sensor/status on every recognition and as a heartbeat. Behaviour:
`agv_nodes.position_sensor.core`.
"""

from __future__ import annotations

import sys

from agv_nodes.core_node import CoreNode, spin_main
from agv_nodes.markers import THRESHOLDS
from agv_nodes.params import Parameters
from agv_nodes.position_sensor.core import PositionSensorCore, SensorProcessing


class PositionSensorNode(CoreNode):
    """Parameters -> PositionSensorCore -> ports."""

    def __init__(self) -> None:
        super().__init__('position_sensor')
        p = Parameters(self)
        unit = p.choice('sensor_unit', 'sensor1', 'Table 7.1 threshold set used unless '
                        'white_thresholds/black_thresholds are given', ('sensor1', 'sensor2'))
        white = p.numbers('white_thresholds', [], 'THRON per detector 1-8, x4 running-sum '
                          'units (empty = Table 7.1 of sensor_unit)', 8)
        black = p.numbers('black_thresholds', [], 'THROFF per detector 1-8 (empty = Table 7.1)',
                          8)
        d = SensorProcessing()
        sp = SensorProcessing(
            white=tuple(int(v) for v in white) or THRESHOLDS[unit]['white'],
            black=tuple(int(v) for v in black) or THRESHOLDS[unit]['black'],
            min_consecutive_matches=p.integer(
                'min_consecutive_matches', d.min_consecutive_matches, 'equal matches in '
                'successive snapshots before a recognition (thesis 7.1.4: 2; listing: 1)', 1, 10),
            run_length=p.integer('run_length', d.run_length, 'running-sum filter length in '
                                 'snapshots (thesis 5.2.2.2: 4; 2 reads markers to 2 m/s, '
                                 'bench/recognition_bench.py); thresholds scale by n/4', 1, 8),
            invalid_band=p.choice('invalid_band', d.invalid_band, 'a detector between its '
                                  'thresholds: invalid (thesis 5.2.3: no CODE that snapshot) or '
                                  'hold (keeps its last decision; a recognition still needs one '
                                  'snapshot with every detector decided)', ('invalid', 'hold')),
            decoder=p.choice('decoder', d.decoder, 'how the navigating table is read: '
                             'sequence (each detector column reads the passing card in time, '
                             'besides the thesis rule) or snapshot (thesis 5.2.3 only)',
                             ('sequence', 'snapshot')),
            sequence_agree=p.integer('sequence_agree', d.sequence_agree, 'detector columns '
                                     'that must read the same card (sequence decoder)', 1, 4),
            sequence_margin=p.number('sequence_margin', d.sequence_margin, 'band units an '
                                     "element's reading must keep from mid-band (sequence "
                                     'decoder)', 0.0, 0.49),
            sequence_run_length=p.integer('sequence_run_length', d.sequence_run_length,
                                          "the sequence decoder's running-sum length in "
                                          'snapshots', 1, 8),
            variant=p.choice('variant', d.variant, "intended design, or the printed listing's "
                             'defects (black-test compare, EDGE search length 5)',
                             ('intended', 'as_listed')),
            heartbeat=p.number('heartbeat', d.heartbeat, 'longest time between status records',
                               0.005, 1.0),
            heartbeat_samples=p.integer('heartbeat_samples', d.heartbeat_samples, 'snapshots '
                                        'between status heartbeats while snapshots arrive',
                                        1, 1000),
            adc_timeout=p.number('adc_timeout', d.adc_timeout, 'seconds without a snapshot '
                                 'before adc_stale is reported', 0.005, 5.0),
        )
        for name, value, reason in sp.check():
            p.fail(name, value, reason)
        self.attach(PositionSensorCore(sp), p)


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes position_sensor [--ros-args ...]."""
    return spin_main(PositionSensorNode, args)


if __name__ == '__main__':
    sys.exit(main())
