"""The position sensor's C kernel gives the results of the Python code it stands in for.

`agv_nodes/position_sensor/_thresh.c` (built by `pip install -e .`, as the README installs the
package) does SUBT, TOTAL and THRESH and the sequence decoder's running sum on the core's own
lists; `kernels: python` runs the Python code. Two cores, one each way, are fed the same
snapshots (a lock-step run's, and seeded random ones with a table switch) and must return the
same records and hold the same state after every snapshot; a core switching between the two at
random must match too. A whole truck in lock step is run both ways: every record the same.
"""

from __future__ import annotations

import copy
from dataclasses import replace
import itertools
import random
import struct
from typing import Any

import pytest

from agv_nodes.harness import DEMO_PROGRAMME, submit, truck
from agv_nodes.markers import DARK_FIELDS, LIT_FIELDS, LOCATION_TABLE, STOP_VIEWS, THRESHOLDS
from agv_nodes.position_sensor import kernels
from agv_nodes.position_sensor.core import PositionSensorCore
from agv_nodes.position_sensor.settings import SensorProcessing
from agv_nodes.records.codec import codec
from agv_nodes.settings import SettingError, build

pytestmark = pytest.mark.timeout(300)

Event = tuple[str, dict[str, Any], float]  # (record, fields, now), as on_record takes them
# compared apart, or not state (_thresh: a Python core's, counted in _compare)
SKIP = {'p', '_c_thresh', '_c_levels', '_thresh', 'notes', '_sequence'}


def _lock_step(overrides: dict | None = None) -> tuple[Any, list[tuple[str, bytes, float]]]:
    """Run the first 60 s of the demonstration programme: the truck, every record it sent."""
    h = truck('demo_1983', seed=1, overrides=overrides)
    tape: list[tuple[str, bytes, float]] = []
    h.taps.append(lambda record, raw, now: tape.append((record, raw, now)))
    for text in DEMO_PROGRAMME:
        submit(h, text)
    h.run(60.0)
    return h, tape


@pytest.fixture(scope='module')
def default_run() -> tuple[Any, list[tuple[str, bytes, float]]]:
    return _lock_step()


@pytest.fixture(scope='module')
def real_inputs(default_run) -> list[Event]:
    """Decode the position sensor's inputs in that run: ADC snapshots, navigation's commands."""
    c = codec()
    events = []
    for record, raw, now in default_run[1]:
        if record == 'adc_snapshot':  # the world's link carries no E2E protection
            events.append((record, c[record].decode(raw, integrity='none'), now))
        elif record == 'position_sensor_command':
            events.append((record, c[record].decode(raw), now))
    return events


def _state(core: PositionSensorCore) -> dict[str, Any]:
    """Everything the core and its sequence decoder hold, floats of the levels as their bits."""
    state = {k: v for k, v in vars(core).items() if k not in SKIP}
    state['_sequence'] = dict(vars(core._sequence))
    before = core._sequence._before
    state['levels'] = None if before is None else struct.pack(f'{len(before)}d', *before)
    return state


def _settings(**values: Any) -> SensorProcessing:
    return build(SensorProcessing, values)


def _code(core: PositionSensorCore) -> str:
    """Which code the core runs: 'c', 'python', or something else."""
    functions = (core._c_thresh, core._c_levels)
    if functions == (None, None):
        return 'python'
    c = kernels.compiled
    return 'c' if c is not None and functions == (c.thresh, c.levels) else repr(functions)


def _compare(events: list[Event], **values: Any) -> dict[str, int]:
    """Feed `events` to a C core, a Python core and one switching at random; all must agree."""
    c = PositionSensorCore(_settings(kernels='c', **values))
    py = PositionSensorCore(_settings(kernels='python', **values))
    mixed = PositionSensorCore(_settings(kernels='c', **values))
    assert (_code(c), _code(py)) == ('c', 'python')
    rng = random.Random(11)
    seen = {'snapshots': 0, 'recognitions': 0, 'valid': 0, 'held': 0, 'levels': 0}
    thresh = py._thresh

    def counted(lit: Any, dark: Any, row: list[int]) -> tuple[int, bool, bool]:
        code, valid, decisive = thresh(lit, dark, row)
        seen['held'] += valid and not decisive  # a detector in its band kept its decision
        return code, valid, decisive

    py._thresh = counted  # type: ignore[method-assign]
    for k, (record, fields, now) in enumerate(events):
        mixed._c_thresh = kernels.compiled.thresh if rng.random() < 0.5 else None
        mixed._c_levels = kernels.compiled.levels if rng.random() < 0.5 else None
        want = py.on_record(record, fields, now)
        assert c.on_record(record, fields, now) == want, (k, record, fields)
        assert mixed.on_record(record, fields, now) == want, (k, record, fields)
        state = _state(py)
        assert _state(c) == state, (k, record, fields)
        assert _state(mixed) == state, (k, record, fields)
        if record == 'adc_snapshot':
            seen['snapshots'] += 1
            seen['recognitions'] += want is not None
            seen['valid'] += not py.invalid
            seen['levels'] += state['levels'] is not None
    return seen


def test_the_kernel_is_built_where_the_package_is_installed():
    assert kernels.compiled is not None, 'agv_nodes/position_sensor/_thresh.c was not built'
    assert kernels.select('auto') is kernels.compiled
    assert kernels.select('c') is kernels.compiled
    assert kernels.select('python') is None
    assert _code(PositionSensorCore()) == 'c'  # the default: auto


def test_a_bad_choice_or_c_unbuilt_is_refused(monkeypatch):
    with pytest.raises(ValueError, match="'fortran' is not one of auto, c, python"):
        kernels.select('fortran')
    monkeypatch.setattr(kernels, 'compiled', None)
    assert kernels.select('auto') is None
    assert _code(PositionSensorCore(_settings(kernels='auto'))) == 'python'
    with pytest.raises(ValueError, match="position sensor kernels: 'c' asks for the compiled"):
        kernels.select('c')
    with pytest.raises(SettingError, match="kernels.*'c' asks for the compiled kernels"):
        _settings(kernels='c')  # the node's parameters: one line naming key and value
    with pytest.raises(ValueError, match="'c' asks for the compiled kernels"):
        PositionSensorCore(replace(_settings(), kernels='c'))


@pytest.mark.parametrize('variant', ['intended', 'as_listed'])
@pytest.mark.parametrize('invalid_band', ['invalid', 'hold'])
@pytest.mark.parametrize('decoder', ['sequence', 'snapshot'])
@pytest.mark.parametrize('runs', [(4, 2), (1, 8), (8, 1)])
def test_a_lock_step_runs_snapshots_give_the_same_results(real_inputs, variant, invalid_band,
                                                          decoder, runs):
    run_length, sequence_run_length = runs
    seen = _compare(real_inputs, variant=variant, invalid_band=invalid_band, decoder=decoder,
                    run_length=run_length, sequence_run_length=sequence_run_length)
    assert seen['snapshots'] > 20_000
    assert seen['valid'] > 1000 and seen['recognitions'] > 0
    if invalid_band == 'invalid':
        assert seen['held'] == 0
    elif variant == 'as_listed' and run_length == 1:
        assert seen['held'] == 0  # a TOTAL under 256: its high byte 0 is never above THROFF's
    else:
        assert seen['held'] > 100 and seen['snapshots'] - seen['valid'] < 100
    assert (seen['levels'] > 10_000) == (decoder == 'sequence')


def _random_inputs(seed: int) -> list[Event]:
    """Make seeded snapshots and a table switch to positioning and back mid-stream.

    Steady cards, levels about each threshold, extremes, lit below dark; and a command that
    changes nothing.
    """
    rng = random.Random(seed)
    white, black = THRESHOLDS['sensor1']['white'], THRESHOLDS['sensor1']['black']
    codes = [code for code, _ in LOCATION_TABLE] + [code for code, _, _ in STOP_VIEWS]
    events: list[Event] = []
    now, card = 0.0, None
    for k in range(6000):
        now += 1 / 340
        if k in (1500, 3000, 4500):
            table, epoch = {1500: ('positioning', 1), 3000: ('positioning', 1),
                            4500: ('navigating', 2)}[k]
            events.append(('position_sensor_command', {'table': table, 'epoch': epoch}, now))
        if k % 40 == 0:  # a card in view for a while, or none
            card = rng.choice(codes) if rng.random() < 0.6 else None
        lit, dark = [], []
        for d in range(8):
            dark_d = rng.choice((0, 0, 5, 12, 40, 255)) if rng.random() < 0.1 \
                else rng.randint(3, 20)
            kind = rng.random()
            if kind < 0.08:
                lit_d = rng.choice((0, 255))  # extremes
            elif kind < 0.14:
                lit_d = rng.randint(0, dark_d)  # lit at or below dark: SUBT clamps to 0
            elif kind < 0.45:  # about a threshold: white, black or in the band
                level = rng.choice((white[d], black[d])) / 4 + rng.uniform(-6, 6)
                lit_d = dark_d + round(level)
            elif card is not None:
                bit = card >> (7 - d) & 1
                level = white[d] * 1.3 / 4 if bit else black[d] / 1.3 / 4
                lit_d = dark_d + round(level) + rng.randint(-2, 2)
            else:
                lit_d = rng.randint(0, 255)
            lit.append(min(255, max(0, lit_d)))
            dark.append(dark_d)
        fields = dict(zip(LIT_FIELDS, lit, strict=True)) | dict(zip(DARK_FIELDS, dark,
                                                                    strict=True))
        events.append(('adc_snapshot', fields, now))
    return events


@pytest.mark.parametrize('variant', ['intended', 'as_listed'])
@pytest.mark.parametrize('invalid_band', ['invalid', 'hold'])
@pytest.mark.parametrize('decoder', ['sequence', 'snapshot'])
def test_random_snapshots_give_the_same_results(variant, invalid_band, decoder):
    events = _random_inputs(3)
    totals = {'recognitions': 0, 'valid': 0, 'held': 0, 'levels': 0}
    for run_length, sequence_run_length in itertools.product((1, 4, 8), repeat=2):
        seen = _compare(events, variant=variant, invalid_band=invalid_band, decoder=decoder,
                        run_length=run_length, sequence_run_length=sequence_run_length,
                        min_consecutive_matches=1)
        assert seen['snapshots'] == 6000
        for key in totals:
            totals[key] += seen[key]
    assert totals['recognitions'] > 50 and totals['valid'] > 1000
    if invalid_band == 'hold':
        assert totals['held'] > 1000
    else:
        assert totals['held'] == 0 and 9 * 6000 - totals['valid'] > 1000
    assert (totals['levels'] > 10_000) == (decoder == 'sequence')


def test_a_whole_truck_sends_the_same_records_with_either_kernel(default_run):
    """The first 60 s of the demonstration programme, every record's bytes and time compared."""
    c, tape_c = default_run
    py, tape_py = _lock_step({'position_sensor': {'kernels': 'python'}})
    assert _code(c.cores['position_sensor']) == 'c'
    assert _code(py.cores['position_sensor']) == 'python'
    statuses = [raw for record, raw, _ in tape_c if record == 'position_sensor_status']
    assert len(tape_c) > 50_000 and len(statuses) > 1000
    assert tape_c == tape_py


def test_a_core_with_the_kernel_deep_copies_and_the_copy_runs_on_alike(real_inputs):
    """Tests fork a truck's state with copy.deepcopy: the kernel's functions travel with it."""
    core = PositionSensorCore(_settings(kernels='c'))
    half = len(real_inputs) // 2
    for event in real_inputs[:half]:
        core.on_record(*event)
    twin = copy.deepcopy(core)
    assert _code(twin) == 'c'
    for record, fields, now in real_inputs[half:]:
        assert twin.on_record(record, fields, now) == core.on_record(record, fields, now)
    assert _state(twin) == _state(core)


@pytest.mark.parametrize('as_listed', [False, True])
@pytest.mark.parametrize('hold', [False, True])
def test_thresh_matches_the_python_code_on_any_ints(as_listed, hold):
    """Negative and large values too (never a snapshot's), held decisions None, 0 and 1."""
    rng = random.Random(int(as_listed) * 2 + hold)
    py = PositionSensorCore(_settings(kernels='python', variant='as_listed' if as_listed
                                      else 'intended', invalid_band='hold' if hold else 'invalid'))

    def ints(top: int) -> list[int]:
        return [rng.randint(-top, top) for _ in range(8)]

    for _ in range(20_000):
        top = rng.choice((300, 3000, 2 ** 40))
        lit, dark, row, totals = ints(top), ints(top), ints(top), ints(4 * top)
        white, black = ints(4 * top), ints(4 * top)
        held = [rng.choice((None, 0, 1)) for _ in range(8)]
        py._total, py._white, py._black, py._held = list(totals), white, black, list(held)
        py_row = list(row)
        want = py._thresh(lit, dark, py_row)
        got = kernels.compiled.thresh(tuple(lit), dark, row, totals, white, black, held,
                                      as_listed, hold)
        assert got == want and type(got[0]) is int
        assert (row, totals, held) == (py_row, py._total, py._held)


def test_levels_match_the_python_code_to_the_bit():
    """Random doubles for THROFF and the band, where each rounding shows."""
    rng = random.Random(4)
    py = PositionSensorCore(_settings(kernels='python', sequence_run_length=1))
    for _ in range(20_000):
        top = rng.choice((255, 2040, 2 ** 40))
        x = [rng.randint(0, top) for _ in range(8)]
        row = [rng.randint(0, top) for _ in range(8)]
        total = [rng.randint(-top, 8 * top) for _ in range(8)]
        black = [rng.uniform(-1, 1) * 10.0 ** rng.randint(-3, 4) for _ in range(8)]
        band = [rng.uniform(1e-6, 1) * 10.0 ** rng.randint(-3, 4) for _ in range(8)]
        py._seq_oldest, py._seq_total = [list(row)], list(total)
        py._seq_black, py._seq_band = black, band
        want = py._sequence_levels(x)
        got = kernels.compiled.levels(x, row, total, black, band)
        assert struct.pack('8d', *got) == struct.pack('8d', *want)
        assert (row, total) == (py._seq_oldest[0], py._seq_total)
        assert all(a is b for a, b in zip(row, x, strict=True))  # x's own items, as row[:] = x


# -- the C functions refuse what they cannot take, and change nothing then -------------------
def _thresh_args() -> list[Any]:
    return [(20,) * 8, [10] * 8, [0] * 8, [0] * 8, [300] * 8, [100] * 8, [None] * 8, False, True]


def _levels_args() -> list[Any]:
    return [[3] * 8, [0] * 8, [0] * 8, [1.0] * 8, [2.0] * 8]


BAD_THRESH = [
    (0, [20] * 7, ValueError), (0, [20.0] * 8, TypeError), (1, None, TypeError),
    (1, [10] * 9, ValueError), (2, (0,) * 8, TypeError), (2, [0] * 7 + ['0'], TypeError),
    (3, [0] * 7 + [None], TypeError), (3, [0] * 7 + [2 ** 60], ValueError),
    (3, [0] * 7 + [2 ** 53 + 1], ValueError), (4, [300] * 7 + [2 ** 70], ValueError),
    (5, {}, TypeError), (6, [None] * 7 + [2], ValueError), (6, [None] * 7 + [0.0], TypeError),
    (6, [None] * 8 + [None], ValueError),
]
BAD_LEVELS = [
    (0, [3] * 9, ValueError), (0, [3.0] * 8, TypeError), (1, (0,) * 8, TypeError),
    (1, [0] * 7, ValueError), (2, [0] * 7 + [-2 ** 60], ValueError),
    (3, [1] * 8, TypeError), (4, [2.0] * 7, ValueError), (4, [2.0] * 7 + [0.0], ZeroDivisionError),
]


# (function, good arguments, what it returns for them)
CALLS = {'thresh': (_thresh_args, (0, True, True)), 'levels': (_levels_args, [1.0] * 8)}


@pytest.mark.parametrize('function, at, value, error',
                         [('thresh', *bad) for bad in BAD_THRESH]
                         + [('levels', *bad) for bad in BAD_LEVELS])
def test_the_functions_refuse_bad_input_and_change_nothing(function, at, value, error):
    make_args, good = CALLS[function]
    call = getattr(kernels.compiled, function)
    assert call(*make_args()) == good  # the good call works
    args = make_args()
    args[at] = value
    before = [list(a) if isinstance(a, list) else a for a in args]
    with pytest.raises(error):
        call(*args)
    assert args == before


def test_a_total_outside_the_limit_is_refused_not_wrapped():
    args = _thresh_args()
    args[3] = [2 ** 53] * 8  # a TOTAL at the limit: the sum would pass it
    with pytest.raises(ValueError, match='outside'):
        kernels.compiled.thresh(*args)
    assert args[3] == [2 ** 53] * 8 and args[2] == [0] * 8


def test_the_functions_take_their_number_of_arguments():
    with pytest.raises(TypeError, match='9 arguments'):
        kernels.compiled.thresh(*_thresh_args()[:8])
    with pytest.raises(TypeError, match='5 arguments'):
        kernels.compiled.levels(*_levels_args(), None)
