"""Camera calibration mode, system 14 (Rajagopalan 1991, App. F.3), in lock step.

The truck stands still over junction_1991's straight tape (along the x axis at y = 0, 58 mm
wide by the layout file), set off it by a known offset and heading; route following in mode
calibration reads the camera and reports the tape's width, position and orientation. The
expected values are the geometry written here from the world's parameters (camera window
L_c ahead of the axle) and the layout's tape width, judged to the thesis's criterion for the
camera (system 1): within one pixel across (1.95 mm) and 1 degree.
"""

from __future__ import annotations

import math

import pytest

from agv_nodes.harness import Harness, submit, truck
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams

pytestmark = pytest.mark.timeout(60)

LAYOUT = load_layout(layout_path('junction_1991'))
TAPE_WIDTH = LAYOUT.paths['main'].width  # 0.058 m, the layout file's
L_C = Concic2Params().camera_distance  # m, the world's camera window ahead of the axle
PIXEL = RouteParams().image.width / 128  # m per column
FRAMES = RouteParams().calibration.frames


class Exec:
    """A scripted executive holding route following in calibration mode."""

    node, period = 'executive', 0.05

    def __init__(self, direction: str) -> None:
        self.command = {'mode': 'calibration', 'srm_angle': 0, 'junction': 'straight',
                        'manoeuvre': 0, 'direction': direction, 'junction_number': 0,
                        'junction_wait': 0, 'leg': 1}
        self.states: list[str] = []
        self.status: dict = {}

    def on_record(self, record, fields, now):
        if record == 'route_status':
            self.status = fields
            if not self.states or self.states[-1] != fields['state']:
                self.states.append(fields['state'])

    def tick(self, now):
        return {'route_command': dict(self.command)}


def calibrate(y: float, heading: float, direction: str = 'forward'
              ) -> tuple[RouteCore, Exec, WorldCore]:
    world = WorldCore(LAYOUT, WorldParams(seed=5, rear_camera=True,
                                          concic2=Concic2Params(model='kinematic')))
    st = world.vehicle.state
    st.x, st.y, st.heading = 1.0, y, heading  # over the straight, clear of the junction at 3 m
    script, route = Exec(direction), RouteCore(RouteParams(vehicle='concic2'))
    h = Harness(world, [script, route], seed=5)
    assert h.run(5.0, until=lambda: route.calibration.result is not None)
    h.run(0.2)
    return route, script, world


@pytest.mark.parametrize('y, heading', [(0.0, 0.0), (0.02, 0.0), (-0.03, 0.1), (0.01, -0.15)])
def test_calibration_reads_the_tape_as_the_geometry_places_it(y, heading):
    route, script, world = calibrate(y, heading)
    r = route.calibration.result
    assert (r.camera, r.frames, r.normal, r.left_out) == ('front', FRAMES, FRAMES, {})
    assert (r.scale_across, r.scale_along) == pytest.approx((0.25 / 128, 0.05 / 64))
    # the window centre's distance from the tape, measured across the window (+ = tape left)
    window_y = y + L_C * math.sin(heading)
    assert r.eps_d == pytest.approx(-window_y / math.cos(heading), abs=PIXEL)
    assert r.eps_theta == pytest.approx(-heading, abs=math.radians(1.0))
    assert r.width == pytest.approx(TAPE_WIDTH, abs=PIXEL)
    assert r.width_error == pytest.approx(r.width - RouteParams().calibration.tape_width)
    assert r.eps_d_spread < PIXEL and r.eps_theta_spread < math.radians(1.0)
    # route_status shows it (App. F.3's console): mm and degrees, and the mode ran, then ended
    assert script.states[-2:] == ['calibrating', 'idle']
    assert script.status['lateral_error'] == round(r.eps_d * 1000)
    assert script.status['steering'] == round(math.degrees(r.eps_theta))
    assert world.vehicle.state.speed == 0.0 and not route.motor_on


def test_the_rear_camera_is_read_in_the_frame_of_reverse_travel():
    route, _, _ = calibrate(0.02, 0.0, 'reverse')
    r = route.calibration.result
    assert (r.camera, r.normal) == ('rear', FRAMES)
    # facing backwards, the tape (y = 0) lies to the window's left of travel when the truck
    # stands at y = +0.02
    assert r.eps_d == pytest.approx(0.02, abs=PIXEL)
    assert r.width == pytest.approx(TAPE_WIDTH, abs=PIXEL)


def test_calibration_off_the_tape_says_so_and_measures_nothing():
    route, script, _ = calibrate(0.3, 0.0)
    r = route.calibration.result
    assert (r.normal, r.left_out) == (0, {'absent': FRAMES}) and math.isnan(r.width)
    assert route.notes.texts()[-1].endswith(f'no normal track in any frame ({FRAMES} absent)')
    assert script.states[-1] == 'idle' and script.status['lateral_error'] == 0


def test_a_calibrate_task_runs_the_mode_and_completes_with_the_result_said():
    h = truck('junction_1991', seed=1)
    h.run(0.2)
    submit(h, 'calibrate')
    comms, route = h.cores['communications'], h.cores['route_following']
    assert h.run(5.0, until=lambda: comms.results and comms.results[-1][1] == 'completed')
    r = route.calibration.result
    assert r.normal == FRAMES and r.width == pytest.approx(TAPE_WIDTH, abs=PIXEL)
    assert r.eps_d == pytest.approx(0.0, abs=PIXEL)  # the layout's start: on the tape
    said = [t for t in route.notes.texts() if t.startswith('calibration, front camera')]
    assert len(said) == 1 and f'track width {r.width * 1000:.1f} mm' in said[0]
    assert comms.notes.texts()[-1] == "task 1 'calibrate': completed"
    assert h.world.vehicle.state.speed == 0.0
