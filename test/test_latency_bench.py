"""bench/latency_bench.py's arithmetic: the hops of a known chain, and the probe's alignment."""

from __future__ import annotations

import math
from pathlib import Path
import sys

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'bench'))
import latency_bench  # noqa: E402

T = 1 / 340.0


def status(count: int, recognised: int = 0) -> dict:
    return {'sample_count': count & 0xFFFF, 'recognised': recognised}


def chain_run() -> dict[str, list]:
    """Make a synthetic run of 100 snapshots.

    Statuses come 0.5 ms after snapshots 20, 50 (a recognition) and 100; the link 1 ms after
    the recognition, the drive 0.7 ms after that.
    """
    adc = [i * T for i in range(100)]
    statuses = [(adc[c - 1] + 0.0005, status(c, c == 50)) for c in (20, 50, 100)]
    t = statuses[1][0]
    links = [(0.0, {'speed': 40}), (t + 0.001, {'speed': 20})]
    drives = [0.0, t + 0.0017]
    return {'adc_snapshot': adc, 'position_sensor_status': statuses, 'traction_link': links,
            'traction_drive': drives}


def test_hops_of_a_known_chain():
    out = latency_bench.hops(chain_run())
    assert out['adc_to_status'] == pytest.approx([0.0005] * 3)
    assert out['recognition_to_link'] == pytest.approx([0.001])
    assert out['link_to_drive'] == pytest.approx([0.0007])
    assert out['sensor_to_traction'] == pytest.approx([0.0022])


def test_alignment_puts_the_probes_missed_snapshots_back_as_gaps():
    run = chain_run()
    sent = run['adc_snapshot']
    run['adc_snapshot'] = sent[4:30] + sent[33:]  # matched late, then lost three
    aligned = latency_bench.align(run)
    adc = aligned['adc_snapshot']
    assert len(adc) == 100
    assert [i for i, t in enumerate(adc) if math.isnan(t)] == [0, 1, 2, 3, 30, 31, 32]
    assert all(math.isnan(a) or a == b for a, b in zip(adc, sent, strict=True))
    assert aligned['backlog'] == [0, 0, 0]
    assert latency_bench.hops(aligned)['sensor_to_traction'] == pytest.approx([0.0022])


def test_backlog_counts_snapshots_sent_before_a_status_it_had_not_counted():
    run = chain_run()
    run['position_sensor_status'][1] = (run['adc_snapshot'][52] + 0.0001, status(50, 1))
    assert latency_bench.align(run)['backlog'] == [0, 3, 0]
