"""The `thesis` preset (config/presets/concic2_thesis.yaml): the CONCIC-II as the thesis ran it.

The expected values are the thesis's, written here from its text (section in each comment), not
read from the preset or the settings under test.
"""

from __future__ import annotations

import pytest

from agv_nodes.graph.cli import build_parser, options_from
from agv_nodes.graph.model import load_graph
from agv_nodes.graph.parameters import layout_name, truck_graph
from agv_nodes.harness import truck
from agv_nodes.package_share import config_dir
from agv_nodes.route_following.camera_guidance import CameraSteering, Measurement, Validity
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.settings import parameter_file_values, settings_from_file

PRESET = config_dir() / 'presets' / 'concic2_thesis.yaml'
DEMO = config_dir() / 'agv_demo.yaml'


@pytest.mark.timeout(30)
def test_preset_holds_the_thesis_laws_and_gains() -> None:
    """Route following as the chapter 7 experiments ran it."""
    p = settings_from_file(RouteParams, PRESET, 'route_following')
    s = p.steering
    assert (s.law, s.gain_d, s.gain_i) == ('pi', 2.5, 0.07)  # 7.3.1, 7.6: P 2.5, I 0.07
    assert s.gain_theta == 0.0  # 9.1: the orientation offset not fed back
    assert s.integral_form == 'with_dt'  # Eq. 5.6; the 8254 times the PI's interval (6.3.10)
    assert s.set_off_acceleration == 0.0  # 7.3.2: the LM628 ramps both wheels alike
    assert (s.schedule_speed, s.integral_band, s.predict) == (0.0, 0.0, 0.0)  # none of ours
    assert s.absent_frames == 4  # App. F.5: four frames without the tape, motor off
    assert list(p.image.rows) == [3, 29, 55]  # 8.3: the 4th, 30th and 56th of 64 rows
    assert (p.cameras, p.camera_law) == ('lead', 'feedback')  # 7.3: the front camera alone


@pytest.mark.timeout(30)
def test_preset_integral_is_eq_5_6() -> None:
    """A steady 0.01 m offset for 1 s at 20 frames/s gathers G3 x 0.01 m x 1 s (Eq. 5.6)."""
    p = settings_from_file(RouteParams, PRESET, 'route_following')
    law = CameraSteering(p.steering)
    m = Measurement(eps_d=0.01, eps_theta=0.0, validity=Validity.NORMAL, width_px=20.0,
                    rows_used=3, left_edge=False, right_edge=False)
    for _ in range(20):
        theta = law.update(m, 0.05)
    # theta = G2 eps_d + G3 sum(dT eps_d): 2.5 x 0.01 + 0.07 x 20 x 0.05 x 0.01
    assert theta == pytest.approx(0.025 + 0.0007, abs=1e-12)


@pytest.mark.timeout(30)
def test_preset_keeps_the_demo_graphs_overrides() -> None:
    """Every node section of config/agv_demo.yaml is in the preset with the same values."""
    for node in ('world', 'traction', 'executive', 'navigation', 'position_sensor',
                 'communications', 'load_handling', 'route_following'):
        demo = parameter_file_values(DEMO, node)
        preset = parameter_file_values(PRESET, node)
        assert preset[0] == demo[0], node
        for name, value in demo[1].items():
            assert preset[1].get(name) == value, f'{node}: {name}'


@pytest.mark.timeout(30)
def test_agv_launch_takes_the_preset() -> None:
    """`agv-launch --params PRESET` starts the camera truck on the thesis's circle floor."""
    args = build_parser().parse_args(['--params', str(PRESET)])
    options = options_from(args)
    assert options.params == PRESET
    graph = truck_graph(load_graph(options.graph), options)
    assert layout_name(graph, options) == 'tape_1991'
    names = {n.name for n in graph.nodes}
    assert 'route_following' in names and 'traction' not in names  # the CONCIC-II's graph


@pytest.mark.timeout(60)
def test_lock_step_truck_takes_the_preset() -> None:
    """The harness builds the camera truck's cores from the preset, each section accepted."""
    h = truck('tape_1991', params_file=PRESET)
    route = h.cores['route_following'].p
    assert route.vehicle == 'concic2'  # from the layout
    assert route.steering.integral_form == 'with_dt'
    assert list(route.image.rows) == [3, 29, 55]
