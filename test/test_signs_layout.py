"""signs_1991: the six road signs decoded, junction turns, the layout's sign keys, the watchdog.

Lock step with the world core and route following's core (Rajagopalan 1991, 4.3, App. F.6;
6.3.11 for the CONCIC-II's 60 ms computer watchdog).
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from agv_nodes.harness import Harness
from agv_nodes.route_following.camera_guidance import sign_name
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import Layout, LayoutError, layout_path, load_layout
from agv_nodes.world.settings import Concic2Params, WorldParams
from agv_nodes.world.tape_layout import branch_ends

# Camera-mode runs here time and place the truck as the kinematic CONCIC-II drives (the default
# is the dynamic model): pinned, not given looser tolerances.
KINEMATIC = Concic2Params(model='kinematic')


class Script:
    """A stand-in executive: camera mode, one decision for the first junction, then straight.

    It keeps the route_status records' states and the branch flags once a sign is behind.
    """

    node, period = 'executive', 0.05

    def __init__(self, junction: str) -> None:
        self.junction = junction
        self.states: list[str] = []
        self.flags: tuple[int, int, int] | None = None  # (left, right, straight), sign passed
        self.met = 0

    def on_record(self, record, fields, now):
        if record != 'route_status':
            return None
        if not self.states or self.states[-1] != fields['state']:
            if self.states and self.states[-1] == 'sign' and self.flags is None:
                self.flags = (fields['sign_left'], fields['sign_right'], fields['sign_straight'])
            self.states.append(fields['state'])
        self.met = fields['junctions']
        return None

    def tick(self, now):
        first = self.met == 0
        return {'route_command': dict(mode='camera', srm_angle=0, manoeuvre=0, leg=1,
                                      junction=self.junction if first else 'straight',
                                      junction_number=1 if first else self.met + 1)}


def _on_sign(index: int, junction: str, speed: float, before: float = 0.45,
             seed: int = 7) -> tuple[Layout, WorldCore, RouteCore, Script, Harness]:
    """signs_1991 with the camera `before` m short of sign `index`'s patch."""
    lay = load_layout(layout_path('signs_1991'))
    sign = lay.signs[index]
    lay.start_path, lay.start_at = sign['path'], sign['at'] - 0.15 - before
    # Where the window meets each sign and the branch after a set time: the kinematic model.
    world = WorldCore(lay, WorldParams(seed=seed, concic2=KINEMATIC))
    route = RouteCore(RouteParams(vehicle='concic2', camera_speed=speed))
    script = Script(junction)
    return lay, world, route, script, Harness(world, [script, route])


def test_the_layout_has_every_sign_and_its_branches_lead_somewhere():
    lay = load_layout(layout_path('signs_1991'))
    assert {s['type'] for s in lay.signs} == {'P11', 'P12', 'P21', 'P22', 'R1', 'R2'}
    assert lay.vehicle == 'concic2' and lay.kind == 'tape'
    for sign in lay.signs:  # a sign without a straight stands where its tape ends
        assert sign['end'] == ('straight' not in sign['branches'])
        for tid in sign['tapes'].values():
            assert not tid.startswith('sign')  # every branch is a tape of the circuit
    lines = branch_ends(lay.signs, lay.paths)
    assert len(lines) == len(lay.signs) and 'stub' not in ''.join(lines)
    loop = lay.paths['loop']
    assert loop.closed and loop.length == pytest.approx(10.0 + 2 * math.pi * 2.95, abs=0.01)


@pytest.mark.timeout(90)
@pytest.mark.parametrize('speed', [0.16, 0.47, 0.8])
def test_each_sign_decodes_at_speed(speed):
    """Rajagopalan 1991, 4.3: 100 % of the signs decoded, straight on where there is a straight.

    A sign without one ends its tape: straight on there, the truck stops (no_branch) with the
    sign's flags read.
    """
    lay = load_layout(layout_path('signs_1991'))
    first = {}
    for i, sign in enumerate(lay.signs):
        first.setdefault(sign['type'], i)
    decoded = {}
    for kind, index in sorted(first.items()):
        _lay, _world, route, script, h = _on_sign(index, 'straight', speed)
        h.run(0.9 / speed + 3.0, until=lambda s=script: s.flags is not None)
        decoded[kind] = sign_name(*script.flags) if script.flags else None
        want = 'following' if 'straight' in lay.signs[index]['branches'] else 'no_branch'
        assert script.states[-1] == want, (kind, script.states)
    assert decoded == {kind: kind for kind in first}


def _turn(index: int, junction: str, speed: float = 0.47):
    lay, world, route, script, h = _on_sign(index, junction, speed, before=0.6)
    h.run(25.0, until=lambda: 'turning' in script.states and route.cam.reported_state()
          == 'following')
    h.run(2.5)  # on along the branch, short of its next sign and of the half circle
    return lay, world, route, script


@pytest.mark.timeout(60)
@pytest.mark.parametrize('index, junction, heading', [(0, 'left', 90.0), (0, 'right', -90.0),
                                                      (4, 'left', 180.0), (4, 'right', 0.0)])
def test_a_branch_is_taken_and_followed(index, junction, heading):
    """App. F.6: stop over the crossing, spin a quarter turn, follow the branch.

    At the cross (R2) on the loop and at the T (R1) where north_c ends on the loop.
    """
    lay, world, route, script = _turn(index, junction)
    sign = lay.signs[index]
    assert script.states[:3] == ['following', 'sign', 'turning'], script.states
    assert route.cam.reported_state() == 'following'
    s = world.vehicle.state
    error = (math.degrees(s.heading) - heading + 180.0) % 360.0 - 180.0
    assert abs(error) < 2.0 and s.speed > 0.4
    branch = lay.paths[sign['tapes'][junction]]
    _along, off, _h = branch.project(*world.vehicle.sensor_point)
    assert abs(off) < 0.005  # the camera on the branch tape
    crossing = lay.paths[sign['path']].pose_at(sign['at'])
    assert math.dist((s.x, s.y), crossing[:2]) > 0.5  # the axle off the crossing, at cruise


# -- the layout file's sign keys --------------------------------------------------------------
def _layout(tmp_path: Path, signs: str, tapes: str = '') -> Path:
    text = f"""layout: t
vehicle: concic2
kind: tape
tapes:
  - {{id: main, start: [0.0, 0.0, 0.0], width: 0.058, segments: [{{straight: 4.0}}]}}
  - {{id: cross, start: [3.971, -2.0, 90.0], width: 0.058, segments: [{{straight: 4.0}}]}}
{tapes}signs:
{signs}
"""
    path = tmp_path / 't.yaml'
    path.write_text(text)
    return path


@pytest.mark.timeout(30)
@pytest.mark.parametrize('sign, words', [
    ('{type: P11, path: main, at: 2.0}', ['signs[0].at', '2.0', 'at: end']),
    ('{type: P21, path: main, at: end}', ['signs[0].at', "'end'", 'straight']),
    ('{type: P21, path: main, at: 3.0}', ['signs[0].at', '3.0', '1.00 m', '1.5 m']),
    ('{type: R1, path: main, at: end, branch: {left: nowhere}}',
     ['signs[0].branch.left', "'nowhere'", 'no other tape']),
    ('{type: R1, path: main, at: end, branch: {straight: 2.0}}',
     ['signs[0].branch.straight', 'R1 turns only left and right']),
    ('{type: P11, path: main, at: end, branch: {left: 0.05}}',
     ['signs[0].branch.left', '0.05', 'outside']),
    ('{type: P21, path: main, at: 1.0, branch: {left: cross}}',
     ['signs[0].branch.left', "'cross'", 'passes 2.971 m from the crossing']),
    ('{type: P21, path: main, at: 1.0, branch: {left: main}}',
     ['signs[0].branch.left', "'main'", 'no other tape']),
    ('{type: P21, path: main, at: 2.0, colour: red}', ['signs[0].colour', 'unknown']),
])
def test_sign_key_errors_name_the_file_key_and_value(tmp_path, sign, words):
    path = _layout(tmp_path, f'  - {sign}')
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    message = str(err.value)
    assert '\n' not in message and message.startswith(f'{path}: key ')
    for word in words:
        assert word in message, message


@pytest.mark.timeout(30)
def test_named_branches_must_cross_at_right_angles_with_room_to_stop(tmp_path):
    slant = '  - {id: slant, start: [2.0, 0.0, 60.0], width: 0.058, segments: [{straight: 3}]}\n'
    path = _layout(tmp_path, '  - {type: P21, path: main, at: 2.0, branch: {left: slant}}',
                   slant)
    with pytest.raises(LayoutError, match=r"branch.left: 'slant' crosses at 30.0 deg"):
        load_layout(path)
    short = '  - {id: short, start: [3.0, 0.0, 90.0], width: 0.058, segments: [{straight: 1}]}\n'
    path = _layout(tmp_path, '  - {type: P21, path: main, at: 2.0, branch: {left: short}}',
                   short.replace('[3.0, 0.0', '[2.0, 0.0'))
    with pytest.raises(LayoutError, match=r"'short' runs 1.00 m .* needs 1.5 m"):
        load_layout(path)


@pytest.mark.timeout(30)
def test_a_sign_at_a_tape_end_cuts_it_square_and_joins_a_named_tape(tmp_path):
    path = _layout(tmp_path, '  - {type: R1, path: main, at: end, branch: {left: cross, '
                             'right: 2.0}}')
    lay = load_layout(path)
    sign = lay.signs[0]
    assert sign['at'] == pytest.approx(4.0 - 0.029) and sign['end']
    assert sign['tapes'] == {'left': 'cross', 'right': 'sign0_right'}
    assert lay.paths['main'].square_ends == (False, True)
    assert lay.paths['sign0_right'].length == pytest.approx(2.0)
    # The camera sees no tape past the square end: over the far edge nothing is dark.
    world = WorldCore(lay, WorldParams(seed=1))
    beyond = world.camera.render(4.026, 0.0, 0.0, noise=False)  # the window just past the end
    assert beyond.sum() == 0  # a rounded end would show 28 mm of tape here
    over = world.camera.render(3.99, 0.0, 0.0, noise=False)  # the end across row 18-19
    assert over[20:, 64].all() and not over[:18, 64].any()


# -- the CONCIC-II's computer watchdog (Rajagopalan 1991, 6.3.11) ----------------------------
@pytest.mark.timeout(30)
def test_watchdog_cuts_the_motors_60_ms_after_the_last_steering_command():
    lay = load_layout(layout_path('signs_1991'))
    world = WorldCore(lay, WorldParams(seed=1))
    assert world.p.concic2.watchdog == pytest.approx(0.06)
    command = {'mode': 'wheel_speeds', 'enable': 1, 'angle': 0, 'left_speed': 470,
               'right_speed': 470}
    while world.time < 3.0:  # cruise, a command every 10 ms as route following sends them
        if world.sample % 3 == 0:
            world.on_record('steering_command', command, world.time)
        world.step()
    last = world.time
    world.on_record('steering_command', command, last)
    speed = world.vehicle.state.speed
    assert speed == pytest.approx(0.47, abs=0.01)
    x0, y0 = world.vehicle.state.x, world.vehicle.state.y
    off_at = None
    while world.time < last + 2.0:
        world.step()
        if off_at is None and not world.vehicle.enable:
            off_at = world.time
    assert off_at is not None and off_at - last <= 0.06 + world.dt + 1e-9
    assert off_at - last > 0.06 - world.dt  # not before the watchdog's time
    st = world.vehicle.state
    assert st.speed == 0.0
    coast = speed * speed / (2.0 * world.p.concic2.coast_deceleration)
    travelled = math.hypot(st.x - x0, st.y - y0)
    assert travelled <= speed * 0.06 + coast + 0.002  # 60 ms at cruise, then the coast down
