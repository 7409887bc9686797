"""agv_nodes.result_cache: computed once per inputs and code, and never wrongly reused."""

from __future__ import annotations

import json

import pytest

from agv_nodes import result_cache
from agv_nodes.world.layout import load_layout
from agv_nodes.world.layout_check import check_errors, check_layout

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv(result_cache.CACHE_ENV, str(tmp_path / 'cache'))
    monkeypatch.setattr(result_cache, '_memory', {})
    return tmp_path / 'cache'


def counting(value):
    calls = []

    def compute():
        calls.append(1)
        return value
    return compute, calls


def test_computed_once_then_read_from_disk_by_a_fresh_process(cache, monkeypatch):
    compute, calls = counting(['a line'])
    assert result_cache.cached('kind', 'inputs', compute) == ['a line']
    assert result_cache.cached('kind', 'inputs', compute) == ['a line']
    assert len(calls) == 1
    (entry,) = (cache / 'kind').glob('*.json')
    assert json.loads(entry.read_text()) == ['a line']
    monkeypatch.setattr(result_cache, '_memory', {})  # as a new process: only the disk
    assert result_cache.cached('kind', 'inputs', compute) == ['a line'] and len(calls) == 1


def test_other_inputs_kind_or_code_compute_afresh(cache, monkeypatch):
    compute, calls = counting([])
    result_cache.cached('kind', 'inputs', compute)
    result_cache.cached('kind', 'other inputs', compute)
    result_cache.cached('other kind', 'inputs', compute)
    assert len(calls) == 3
    monkeypatch.setattr(result_cache, '_memory', {})
    monkeypatch.setattr(result_cache, 'code_digest', lambda: 'changed code')
    result_cache.cached('kind', 'inputs', compute)
    assert len(calls) == 4


def test_off_or_unwritable_computes_every_time_without_error(tmp_path, monkeypatch):
    monkeypatch.setattr(result_cache, '_memory', {})
    monkeypatch.setenv(result_cache.CACHE_ENV, 'off')
    assert result_cache.cache_dir() is None
    compute, calls = counting(1)
    assert result_cache.cached('kind', 'inputs', compute) == 1
    blocked = tmp_path / 'a file'
    blocked.write_text('not a directory')
    monkeypatch.setenv(result_cache.CACHE_ENV, str(blocked))
    monkeypatch.setattr(result_cache, '_memory', {})
    assert result_cache.cached('kind', 'inputs', compute) == 1
    assert len(calls) == 2


def test_a_corrupt_entry_is_computed_again(cache, monkeypatch):
    compute, calls = counting({'ok': True})
    result_cache.cached('kind', 'inputs', compute)
    (entry,) = (cache / 'kind').glob('*.json')
    entry.write_text('{not json')
    monkeypatch.setattr(result_cache, '_memory', {})
    assert result_cache.cached('kind', 'inputs', compute) == {'ok': True} and len(calls) == 2


def test_the_code_digest_covers_every_source_and_parameter_file():
    names = {p.name for p in result_cache.PACKAGE.rglob('*')
             if p.suffix in ('.py', '.yaml') and '__pycache__' not in p.parts}
    assert {'layout_check.py', 'marker_sensor.py', 'vehicles.py', 'parameters.yaml'} <= names
    assert result_cache.code_digest() == result_cache.code_digest()


def test_the_layout_check_verdict_is_the_check_itself(cache, tmp_path):
    """A kept verdict is the drives' own, and a layout edited in place is driven again."""
    layout = tmp_path / 'edge.yaml'
    text = ('layout: edge\nvehicle: electruk\nkind: wire\nsensor: {standoff: 0.3, lateral: 0.45}\n'
            'wires:\n  - id: A\n    start: [0.0, 0.0, 0.0]\n    segments:\n'
            '      - straight: 6.0\n'
            'markers:\n  - {kind: location, identity: 0, path: A, at: 3.0, standoff: STANDOFF}\n'
            'start: {path: A, at: 0.5}\n')
    layout.write_text(text.replace('STANDOFF', '0.300'))
    lay = load_layout(layout)
    assert check_errors(lay) == check_layout(lay).errors() == []
    layout.write_text(text.replace('STANDOFF', '0.370'))  # now beyond what the sensor reads
    lay = load_layout(layout)
    errors = check_errors(lay)
    assert errors == check_layout(lay).errors() and len(errors) == 1
    assert 'does not read it' in errors[0]


def test_the_marker_sensor_calibration_kept_on_disk_is_the_threshold_experiment_itself(cache):
    """The belt runs read back from disk equal, to the bit, the ones the optics compute."""
    from agv_nodes.world import marker_sensor
    from agv_nodes.world.settings import SensorParams

    params = SensorParams()
    key = marker_sensor.belt_key(params)
    marker_sensor._belt_runs.cache_clear()
    try:
        computed = marker_sensor._belt_runs(key)  # computed, and written to the cache
        assert list((cache / 'belt_runs').iterdir())
        result_cache._memory.clear()
        marker_sensor._belt_runs.cache_clear()
        read = marker_sensor._belt_runs(key)  # from the disk
        assert read == computed == tuple(tuple(d) for d in marker_sensor._run_belt(key))
        assert marker_sensor.calibrate(params) == marker_sensor.calibrate(params)
    finally:
        marker_sensor._belt_runs.cache_clear()
