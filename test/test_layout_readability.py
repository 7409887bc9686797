"""The layout check agrees with the simulated truck: it refuses exactly the cards the truck misses.

Each room is driven by the whole lock-step truck (agv_nodes.harness: the world, its marker
sensor and noise, and every node core, steered and sped by the executive's `pass N` task) with
several seeds, and each card counts as read on a drive when the position sensor recognises its
identity within a second of the world's `marker_passed` event for it. That truth is set beside
`check_layout`'s grade of the same card:

- read on every drive: the check must not refuse it (readable, or marginal);
- read on none: the check must refuse it (unreadable), naming how to go on;
- read on some: it lies at the edge, and the check must say so (marginal or unreadable).

The rooms put cards on straights near the standoff and angle at which the simulated sensor
stops reading, on and after bends where the truck's off-tracking turns the lens away (Baker
1983, 6.3.2), so that each room holds cards the truck reads and cards it misses.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from agv_nodes.harness import submit, truck
from agv_nodes.records import codec
from agv_nodes.world.layout import load_layout
from agv_nodes.world.layout_check import check_layout
from agv_nodes.world.readability import expected_identity

SEEDS = (1, 2, 3)
WINDOW = 1.0  # s either side of the world's marker_passed event a recognition counts in

ROOMS = {
    # cards on a straight either side of the standoffs and turns the sensor reads at cruise
    'straight': ('[{straight: 16.0}]', 3, [
        '{kind: location, identity: 0, path: A, at: 3.0, standoff: 0.335}',
        '{kind: location, identity: 1, path: A, at: 6.5, standoff: 0.360}',
        '{kind: location, identity: 2, path: A, at: 10.0, standoff: 0.330, yaw: 20}',
        '{kind: location, identity: 3, path: A, at: 13.5, standoff: 0.300, yaw: -12}']),
    # an R 3 m right bend: one card before it, two on it, one after it
    'right_bend': ('[{straight: 4.0}, {arc: 3.0, angle: -90}, {straight: 8.0}]', 3, [
        '{kind: location, identity: 0, path: A, at: 3.0, standoff: 0.340}',
        '{kind: location, identity: 1, path: A, at: 6.0, standoff: 0.300}',
        '{kind: location, identity: 2, path: A, at: 8.2, standoff: 0.280}',
        '{kind: location, identity: 3, path: A, at: 10.0, standoff: 0.310}']),
    # the demo's 180 degree left bend at 2.5 m: on it, just after it, well after it
    'left_bend': ('[{straight: 4.0}, {arc: 2.5, angle: 180}, {straight: 6.0}]', 2, [
        '{kind: location, identity: 0, path: A, at: 10.545}',
        '{kind: location, identity: 1, path: A, at: 12.154}',
        '{kind: location, identity: 2, path: A, at: 15.854}']),
}


def write_room(tmp_path: Path, name: str) -> Path:
    """Write room `name` of ROOMS as a one-wire Electruk layout."""
    segments, _last, markers = ROOMS[name]
    file = tmp_path / f'{name}.yaml'
    file.write_text(f'layout: {name}\nvehicle: electruk\nkind: wire\n'
                    'sensor: {standoff: 0.300, lateral: 0.45}\n'
                    f'wires:\n  - id: A\n    start: [0.0, 0.0, 0.0]\n    segments: {segments}\n'
                    'markers:\n' + ''.join(f'  - {m}\n' for m in markers)
                    + 'start: {path: A, at: 0.5}\n')
    return file


def drive(file: Path, last: int, seed: int) -> dict[int, bool]:
    """Drive the lock-step truck past every card (`pass <last>`); return card index -> read."""
    h = truck(str(file), seed=seed, overrides={'world': {'layout_check': 'warn'}})
    status = codec()['position_sensor_status']
    recognitions: list[tuple[float, int]] = []

    def tap(record: str, raw: bytes, now: float) -> None:
        if record == 'position_sensor_status':
            fields = status.decode(raw, integrity=h.integrity)
            if fields['recognised']:
                recognitions.append((now, fields['identity']))

    h.taps.append(tap)
    markers = h.world.layout.markers
    submit(h, f'pass {last}')
    passed: dict[int, float] = {}

    def all_passed() -> bool:
        for e in h.events:
            if e['event'] == 'marker_passed':
                for i, m in enumerate(markers):
                    if i not in passed and e['marker_kind'] == m.kind and \
                            e['identity'] == m.identity + (m.kind == 'stop'):
                        passed[i] = e['time']
        h.events.clear()
        return len(passed) == len(markers) and h.now > max(passed.values()) + WINDOW

    assert h.run(60.0, until=all_passed), f'{file.stem}: the truck passed only {sorted(passed)}'
    return {i: any(abs(t - passed[i]) <= WINDOW and ident == expected_identity(m)
                   for t, ident in recognitions)
            for i, m in enumerate(markers)}


@pytest.mark.timeout(300)
@pytest.mark.parametrize('room', sorted(ROOMS))
def test_the_check_refuses_exactly_the_cards_the_truck_cannot_read(tmp_path, room):
    file = write_room(tmp_path, room)
    report = check_layout(load_layout(file))
    truth = [drive(file, ROOMS[room][1], seed) for seed in SEEDS]
    rows = []
    for i, p in enumerate(report.passages):
        reads = sum(t[i] for t in truth)
        rows.append((p.marker.name, f'{p.standoff:.3f} m {p.angle:+.1f} deg', p.grade or 'yes',
                     f'read on {reads} of {len(SEEDS)} drives'))
        if reads == len(SEEDS):
            assert p.grade != 'unreadable', rows
        elif reads == 0:
            assert p.grade == 'unreadable', rows
        else:
            assert p.grade in ('marginal', 'unreadable'), rows
    print('\n'.join(' | '.join(r) for r in rows))
    # The room tries both sides of the edge: the truck reads some cards and misses others.
    reads = [sum(t[i] for t in truth) for i in range(len(report.passages))]
    assert 0 in reads and len(SEEDS) in reads, rows
    for line in report.errors():
        assert 'unreadable marker' in line and 'layout_check:=warn' in line


@pytest.mark.timeout(120)
def test_a_refusal_names_the_margin_and_a_marginal_card_is_only_warned(tmp_path):
    file = write_room(tmp_path, 'straight')
    report = check_layout(load_layout(file))
    by_name = {p.marker.name: p for p in report.passages}
    far = by_name['L1']  # 360 mm: beyond the standoff the sensor reads at
    assert far.grade == 'unreadable'
    (line,) = [e for e in report.errors() if "'L1'" in e]
    assert 'standoff 0.360 m' in line and 'read if moved' in line and 'mm in' in line
    # every refusal line is a warning line plus the way to go on; marginal cards only warn
    assert all(p.grade != 'marginal' or not any(f"'{p.marker.name}'" in e
                                                for e in report.errors())
               for p in report.passages)
