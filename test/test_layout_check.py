"""The layout check (agv_nodes/world/layout_check.py) and agv-layout check."""

import math
from pathlib import Path
import re
import subprocess
import sys

import pytest

from agv_nodes.harness import truck
from agv_nodes.package_share import config_dir
from agv_nodes.world.layout import LayoutError, load_layout
from agv_nodes.world.layout_check import check_layout, enforce
from agv_nodes.world.marker_sensor import READ_ANGLE, READ_STANDOFF, axis_on_card, lens_position

SHIPPED = sorted((config_dir() / 'layouts').glob('*.yaml'))
LATERAL = 0.45


def write_layout(tmp_path: Path, name: str, segments: str, markers: str) -> Path:
    """Write a one-wire Electruk layout; `markers` are YAML flow mappings, one a line."""
    file = tmp_path / f'{name}.yaml'
    file.write_text(f'layout: {name}\nvehicle: electruk\nkind: wire\n'
                    f'sensor: {{standoff: 0.300, lateral: {LATERAL}}}\n'
                    f'wires:\n  - id: A\n    start: [0.0, 0.0, 0.0]\n    segments: {segments}\n'
                    'markers:\n' + ''.join(f'  - {m}\n' for m in markers.splitlines())
                    + 'start: {path: A, at: 0.5}\n')
    return file


def straight(tmp_path: Path, name: str, **card: float) -> Path:
    """Write a straight 12 m wire with one location marker at 6 m, with `card` set on it."""
    extra = ''.join(f', {k}: {v}' for k, v in card.items())
    return write_layout(tmp_path, name, '[{straight: 12.0}]',
                        f'{{kind: location, identity: 0, path: A, at: 6.0{extra}}}')


@pytest.mark.timeout(60)
@pytest.mark.parametrize('file', SHIPPED, ids=[f.stem for f in SHIPPED])
def test_every_shipped_layout_passes(file):
    report = check_layout(load_layout(file))
    assert report.errors() == []
    assert len(report.passages) == len(report.layout.markers)
    lo, hi = READ_STANDOFF
    for p in report.passages:
        assert p.passed and p.in_range, p.marker.name
        assert lo <= p.standoff <= hi and abs(p.angle) <= READ_ANGLE
        assert p.grade == '' and p.problem() == '', p.marker.name


@pytest.mark.timeout(60)
def test_the_demo_layout_drives_each_marker_as_expected():
    report = check_layout(load_layout(config_dir() / 'layouts' / 'demo_1983.yaml'))
    by_name = {p.marker.name: p for p in report.passages}
    # On the straights the truck carries the lens square to the cards at 300 mm.
    for name in ('L0', 'W0.1', 'L2', 'W2.1', 'W2.2'):
        assert by_name[name].standoff == pytest.approx(0.300, abs=0.003)
        assert abs(by_name[name].angle) < 2.0
    # 1.5 m after the 180 degree bends the truck still heads outward: the axis meets L1 and L3
    # turned and farther off (the route map's SRM landings pass them at least that badly).
    for name in ('L1', 'L3'):
        assert 5.0 < by_name[name].angle < READ_ANGLE
        assert 0.305 < by_name[name].standoff < READ_STANDOFF[1]


@pytest.mark.timeout(60)
@pytest.mark.parametrize(('standoff', 'refused'), [(0.370, True), (0.300, False)])
def test_a_refusal_names_the_card_its_geometry_and_the_way_to_go_on(tmp_path, standoff, refused):
    # Whether the simulated truck reads a card is held against its drives in
    # test_layout_readability.py; here, what the refusal says.
    lay = load_layout(straight(tmp_path, 'edge', standoff=standoff))
    report = check_layout(lay)
    (p,) = report.passages
    assert p.standoff == pytest.approx(standoff, abs=0.002)
    assert abs(p.angle) < 0.5
    if refused:
        (error,) = report.errors()
        x, y = lay.markers[0].centre
        assert error.startswith(f"layout {lay.file}: unreadable marker 'L0' at ({x:.2f}, "
                                f'{y:.2f}): the simulated sensor does not read it as driven '
                                f'(standoff {standoff:.3f} m, angle ')
        assert 'read if moved' in error and error.endswith(
            "to run anyway: -p world:layout_check:=warn (harness: layout_check='warn'); or "
            'move or turn the card as the margin says')
        with pytest.raises(LayoutError, match=re.escape(error)):
            enforce(lay)
        assert enforce(lay, mode='warn') == [error]
    else:
        assert report.errors() == report.warnings() == [] and enforce(lay) == []


@pytest.mark.timeout(60)
@pytest.mark.parametrize(('yaw', 'in_range'), [(12.0, False), (-12.0, False), (8.0, True)])
def test_a_turned_card_is_measured_against_the_thesis_range(tmp_path, yaw, in_range):
    report = check_layout(load_layout(straight(tmp_path, 'turned', yaw=yaw)))
    (p,) = report.passages
    assert p.angle == pytest.approx(yaw, abs=0.5)
    assert p.in_range is in_range  # the thesis's +-10 degrees (Baker 1983, 7.1.4)


def wire_geometry_view(lay, marker) -> tuple[float, float]:
    """(standoff, angle) of a lens carried along the wire's normal: what the layout drew."""
    x, y, h = lay.paths[marker.path].pose_at(marker.at)
    t, u, cos_inc = axis_on_card(lens_position((x, y), h, lay.sensor_lateral), h, marker)
    assert abs(u) < 1e-6
    return t, math.degrees(math.acos(min(1.0, cos_inc)))


def steady_turn_view(radius: float, wheelbase: float, lateral: float,
                     reach: float) -> tuple[float, float]:
    """(standoff, angle) of a card outside a steady left turn, the front axle on the wire.

    The rear axle runs inside, so the truck heads asin(wheelbase / radius) outward of the wire
    at the front axle; the lens is `lateral` along the axis (square to the truck) and the card
    `reach` outside the wire, square to it. With the front axle at (radius, 0), the axis is
    (radius + tau cos a, -tau sin a): it meets the card centre where that is radius + reach
    from the bend's centre, at the bend angle phi behind the front axle.
    """
    a = math.asin(wheelbase / radius)
    b, c = 2.0 * radius * math.cos(a), radius ** 2 - (radius + reach) ** 2
    tau = (-b + math.sqrt(b * b - 4.0 * c)) / 2.0
    phi = math.atan2(tau * math.sin(a), radius + tau * math.cos(a))
    return tau - lateral, math.degrees(a - phi)


@pytest.mark.timeout(60)
def test_off_tracking_on_a_bend_puts_a_card_out_of_range_that_the_wire_puts_in(tmp_path):
    # The demo's bend, 180 degrees left at 2.5 m radius: cards on the truck's right, outside the
    # bend - one 150 degrees round it, one 0.3 m after it, one 4 m after it.
    file = write_layout(tmp_path, 'bend', '[{straight: 4.0}, {arc: 2.5, angle: 180}, '
                        '{straight: 6.0}]',
                        '{kind: location, identity: 0, path: A, at: 10.545}\n'
                        '{kind: location, identity: 1, path: A, at: 12.154}\n'
                        '{kind: location, identity: 2, path: A, at: 15.854}')
    lay = load_layout(file)
    report = check_layout(lay)
    mid, after, far = report.passages
    for p in report.passages:  # the layout as drawn: every card square at 300 mm
        standoff, angle = wire_geometry_view(lay, p.marker)
        assert standoff == pytest.approx(0.300, abs=1e-6) and angle == pytest.approx(0, abs=1e-4)
    # As driven: round the bend the front axle holds the wire while the rear axle cuts inside,
    # and the truck settles to the steady turn's view; just after the bend it has not yet come
    # round.
    standoff, angle = steady_turn_view(2.5, 1.2, LATERAL, LATERAL + 0.300)
    assert (standoff, angle) == (pytest.approx(0.377, abs=0.001), pytest.approx(21.7, abs=0.1))
    assert mid.standoff == pytest.approx(standoff, abs=0.005)
    assert mid.angle == pytest.approx(angle, abs=0.5)
    assert not mid.in_range and not after.in_range
    assert after.angle > 15.0
    assert far.in_range and abs(far.angle) < 2.0
    # whether the truck reads them as driven: test_layout_readability.py (this room, 'left_bend')


def agv_layout(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'agv_nodes.world.layout_cli', *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.timeout(120)
def test_cli_exit_codes(tmp_path):
    ok = agv_layout('check', str(config_dir() / 'layouts' / 'straight_track.yaml'),
                    'sensor_rig')
    assert ok.returncode == 0, ok.stderr
    rows = [line.split() for line in ok.stdout.splitlines()]
    marker_rows = [r for r in rows if len(r) >= 6 and r[5] in ('yes', 'no')]
    assert len(marker_rows) == 8 + 6 and all(r[5] == 'yes' for r in marker_rows)
    assert ok.stderr == ''

    bad = agv_layout('check', str(straight(tmp_path, 'far', standoff=0.37)))
    assert bad.returncode == 1
    (error,) = bad.stderr.splitlines()
    assert error.startswith(f"layout {tmp_path / 'far.yaml'}: unreadable marker 'L0' at (6.00, "
                            '-0.82): the simulated sensor does not read it as driven (standoff '
                            '0.370 m')
    assert re.search(r'^L0 +A +6\.000 +0\.370 +[-+]0\.\d +no +unreadable', bad.stdout, re.M)

    edge = agv_layout('check', str(straight(tmp_path, 'edge', standoff=0.34)))
    assert edge.returncode == 0  # marginal: warned on stderr, not refused
    (warning,) = edge.stderr.splitlines()
    assert "marginal marker 'L0'" in warning and 'unread if' in warning

    missing = agv_layout('check', str(tmp_path / 'none.yaml'))
    assert missing.returncode == 2
    assert len(missing.stderr.splitlines()) == 1 and 'none.yaml' in missing.stderr

    named_wrong = tmp_path / 'wrong.yaml'
    named_wrong.write_text(straight(tmp_path, 'right').read_text())
    invalid = agv_layout('check', str(named_wrong))
    assert invalid.returncode == 2
    (line,) = invalid.stderr.splitlines()
    assert 'wrong.yaml' in line and 'key layout' in line


@pytest.mark.timeout(60)
def test_the_world_refuses_an_unreadable_marker_unless_told_to_warn(tmp_path):
    file = straight(tmp_path, 'refused', standoff=0.37)
    with pytest.raises(LayoutError, match="unreadable marker 'L0'.*layout_check:=warn"):
        truck(str(file))
    h = truck(str(file), overrides={'world': {'layout_check': 'warn'}})
    assert h.world.layout.markers[0].standoff == 0.37
