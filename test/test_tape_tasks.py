"""Tape tasks of the camera truck: the grammar, the itinerary and the legs' junction script."""

import pytest
from tape_floors import straight_tape

from agv_nodes.communications.task_language import TaskError, parse_task
from agv_nodes.executive.core import ExecutiveCore
from agv_nodes.executive.itinerary import itinerary
from agv_nodes.executive.settings import ExecutiveParams
from agv_nodes.executive.tape_legs import TapeLegs

pytestmark = pytest.mark.timeout(30)


def test_a_script_with_waits_otherwise_and_a_reverse_leg() -> None:
    task = parse_task('Tape junctions 1 left, 2 straight wait 3 s, 4 right otherwise random '
                      'for 4.5 m then reverse for 1.5 m').record()
    assert task['op'] == 'tape' and task['then'] == 'reverse'
    assert [task[f'junction_{n}'] for n in range(1, 5)] == ['left', 'straight', 'random', 'right']
    assert [task[f'wait_{n}'] for n in range(1, 5)] == [0, 3, 0, 0]
    assert (task['unscripted'], task['leg_distance'], task['reverse_distance']) == \
        ('random', 45, 15)


def test_a_bare_tape_task_runs_to_the_tape_end_straight_through() -> None:
    task = parse_task('tape').record()
    assert (task['leg_distance'], task['then'], task['unscripted'], task['junction_1']) == \
        (0, 'stay', 'straight', 'straight')
    assert [s.kind for s in itinerary(task)] == ['tape']
    assert [s.kind for s in itinerary(parse_task('tape junctions random then reverse').record())] \
        == ['tape', 'tape_reverse']


@pytest.mark.parametrize('text, column, reason', [
    ('tape junctions 5 left', 16, 'junction number 5 outside 1..4'),
    ('tape junctions 1 up', 18, "expected 'straight' or 'left' or 'right' or 'random', got 'up'"),
    ('tape junctions 1 left, 1 right', 24, 'junction 1 scripted twice'),
    ('tape junctions 1 left wait 16', 28, 'seconds 16 outside 0..15'),
    ('tape for 30 m', 10, 'leg length 30 m outside 0.1..25.5'),
    ('tape for 1.25 m', 10, 'expected leg length in m (e.g. 2.5), got'),
    ('tape then continue', 11, "expected 'reverse', got 'continue'"),
    ('tape junctions 1 left then reverse for 2 m now', 44, "unexpected 'now'"),
])
def test_bad_tape_tasks_name_the_column_and_reason(text: str, column: int, reason: str) -> None:
    with pytest.raises(TaskError) as err:
        parse_task(text)
    assert err.value.column == column and err.value.reason.startswith(reason), err.value


def status(leg: int, state: str = 'following', junctions: int = 0, distance: int = 0) -> dict:
    return {'leg': leg, 'state': state, 'junctions': junctions, 'distance': distance}


def test_each_junction_gets_its_scripted_decision_numbered_in_time() -> None:
    legs = TapeLegs(seed=1, rest_time=0.3)
    task = parse_task('tape junctions 1 left wait 2, 2 right otherwise straight').record()
    route = legs.start(task, kind='tape', length_dm=0, route={'manoeuvre': 0})
    assert (route['mode'], route['direction'], route['junction'], route['junction_number'],
            route['junction_wait']) == ('camera', 'forward', 'left', 1, 2)
    outcome, route = legs.update(status(legs.leg, 'turning', junctions=1), route, 1.0)
    assert outcome.state == 'running'
    assert (route['junction'], route['junction_number'], route['junction_wait']) == \
        ('right', 2, 0)
    outcome, route = legs.update(status(legs.leg, 'following', junctions=2), route, 2.0)
    assert (route['junction'], route['junction_number']) == ('straight', 3)


def test_a_status_of_the_previous_leg_is_not_taken_for_this_one() -> None:
    legs = TapeLegs(seed=1, rest_time=0.3)
    route = legs.start(parse_task('tape').record(), 'tape', 0, {'manoeuvre': 0})
    outcome, _ = legs.update(status(legs.leg - 1, 'no_track', distance=300), route, 1.0)
    assert outcome.state == 'running' and legs.phase == 'driving'


def test_random_choices_follow_the_thesis_draw_and_repeat_with_the_seed() -> None:
    def draws(seed: int) -> list[str]:
        legs = TapeLegs(seed=seed, rest_time=0.3)
        route = legs.start(parse_task('tape junctions random').record(), 'tape', 0, {})
        out = [route['junction']]
        for k in range(1, 40):
            _, route = legs.update(status(legs.leg, junctions=k), route, float(k))
            out.append(route['junction'])
        return out

    first = draws(7)
    assert first == draws(7) and first != draws(8)
    # even -> turn (then even/odd -> left/right), odd -> straight: about half go straight
    assert 10 <= first.count('straight') <= 30 and 'left' in first and 'right' in first


def test_a_leg_with_a_length_stops_at_it_and_is_done_at_rest() -> None:
    legs = TapeLegs(seed=1, rest_time=0.3)
    route = legs.start(parse_task('tape for 2.0 m').record(), 'tape', 20, {})
    assert route['length'] == 20  # dm: route following parks there (test_parking_stops.py)
    outcome, route = legs.update(status(legs.leg, distance=150), route, 1.0)
    assert outcome.state == 'running' and route['mode'] == 'camera'
    outcome, route = legs.update(status(legs.leg, distance=200), route, 2.0)
    assert route['mode'] == 'idle'  # motor-off stop
    outcome, route = legs.update(status(legs.leg, 'idle', distance=202), route, 2.1)
    outcome, route = legs.update(status(legs.leg, 'idle', distance=202), route, 2.3)
    assert outcome.state == 'running'
    outcome, route = legs.update(status(legs.leg, 'idle', distance=202), route, 2.45)
    assert outcome.state == 'done'


def test_a_leg_route_following_parked_short_of_the_centimetre_is_done_at_rest() -> None:
    """Parked (idle) 5 mm short of 2.0 m, the distance may read 199 cm: the leg still ends."""
    legs = TapeLegs(seed=1, rest_time=0.3)
    route = legs.start(parse_task('tape for 2.0 m').record(), 'tape', 20, {})
    outcome, route = legs.update(status(legs.leg, 'idle', distance=199), route, 1.0)
    assert route['mode'] == 'idle' and legs.phase == 'stopping'
    for t in (1.1, 1.45):
        outcome, route = legs.update(status(legs.leg, 'idle', distance=199), route, t)
    assert outcome.state == 'done'


@pytest.mark.parametrize('length_dm, state, expected', [
    (0, 'no_track', 'done'),  # the tape's end ends a leg without a length
    (20, 'no_track', 'lost_track'),  # short of the length: the tape was lost
    (0, 'no_branch', 'no_branch'),
    (0, 'lost', 'lost_track'),
])
def test_how_a_leg_ends(length_dm: int, state: str, expected: str) -> None:
    legs = TapeLegs(seed=1, rest_time=0.3)
    route = legs.start(parse_task('tape').record(), 'tape', length_dm, {})
    outcome = None
    for t in (1.0, 1.2, 1.4):
        outcome, route = legs.update(status(legs.leg, state, distance=120), route, t)
        if outcome.state != 'running':
            break
    assert outcome is not None
    assert (outcome.state if outcome.state == 'done' else outcome.cause) == expected


def executive(guidance: str) -> ExecutiveCore:
    return ExecutiveCore(ExecutiveParams(guidance=guidance))


def task_record(text: str, task_id: int = 1) -> dict:
    task = parse_task(text)
    task.task_id = task_id
    return task.record()


@pytest.mark.parametrize('guidance, text', [('wire', 'tape'), ('camera', 'stop at 2 first')])
def test_a_task_for_the_other_truck_is_rejected(guidance: str, text: str) -> None:
    ex = executive(guidance)
    ex.on_record('comms_status', task_record(text), 0.0)
    assert ex.report['state'] == 'rejected' and ex.report['cause'] == 'bad_task'
    assert ex.mode == 'idle'


def test_the_camera_truck_supervises_route_following_and_communications_only() -> None:
    ex = executive('camera')
    assert ex.route['mode'] == 'idle'
    for t in (0.0, 0.05, 0.1):
        ex.on_record('route_status', status(0, 'idle'), t)
        ex.on_record('comms_status', task_record('tape'), t)
    assert ex.mode == 'running' and ex.route['mode'] == 'camera'
    for k in range(3, 40):  # two seconds without navigation, traction or load: no fault
        t = k * 0.05
        ex.on_record('route_status', status(ex.tape.leg), t)
        ex.on_record('comms_status', task_record('tape'), t)
        ex.tick(t)
    assert ex.mode == 'running', ex.report
    ex.tick(2.5)  # route following silent for 0.55 s
    assert ex.mode == 'failed' and ex.report['cause'] == 'stale_status'
    assert ex.report['subsystem'] == 'route' and ex.route['mode'] == 'idle'


def test_the_reverse_leg_numbers_its_junctions_on_from_the_forward_legs() -> None:
    """The script numbers the task's junctions as its legs meet them (App. F.7's one file)."""
    legs = TapeLegs(seed=1, rest_time=0.3)
    task = parse_task('tape junctions 1 left, 2 right, 3 straight wait 4 then reverse').record()
    route = legs.start(task, 'tape', 0, {})
    assert route['junction'] == 'left'
    _, route = legs.update(status(legs.leg, junctions=1), route, 1.0)
    assert (route['junction'], route['junction_number']) == ('right', 2)
    route = legs.start(task, 'tape_reverse', 0, {})  # the forward leg met one junction
    assert (route['direction'], route['junction'], route['junction_number']) == \
        ('reverse', 'right', 1)
    _, route = legs.update(status(legs.leg, junctions=1), route, 2.0)
    assert (route['junction'], route['junction_wait'], route['junction_number']) == \
        ('straight', 4, 2)
    _, route = legs.update(status(legs.leg, junctions=2), route, 3.0)
    assert (route['junction'], route['junction_wait']) == ('straight', 0)  # no 4th line
    # A new task numbers from 1 again.
    assert legs.start(task, 'tape', 0, {})['junction'] == 'left'


@pytest.mark.timeout(120)
def test_a_decision_the_sign_lacks_fails_the_task_and_stops_the_truck() -> None:
    """tape_1991's second junction is a P22 (right and straight): a scripted left is not there."""
    from agv_nodes.harness import submit, truck

    h = truck('tape_1991', overrides={'world': {'concic2.model': 'kinematic'}})
    ex, comms = h.cores['executive'], h.cores['communications']
    h.run(0.5)
    submit(h, 'tape junctions 1 straight, 2 left')
    assert h.run(40.0, until=lambda: ex.mode == 'failed')
    assert (ex.report['cause'], ex.report['subsystem']) == ('no_branch', 'route')
    h.run(2.0)
    assert abs(h.world.vehicle.state.speed) < 1e-3 and not h.world.vehicle.enable
    assert comms.results[-1][1:] == ('failed', 'no_branch')
    # The executive's line names the junction, the sign the window read, what it offers and the
    # decision: tape_1991's second sign is a P22 (config/layouts/tape_1991.yaml).
    assert any('FAILED no_branch (route): junction 2: sign P22 seen, offering right and '
               'straight; the decision left is not on it' in text for text in ex.notes.texts()), \
        ex.notes.texts()
    # ...and so does the task's report line, from comms_command's junction, sign and decision
    assert any(': FAILED: no branch (route): junction 2: sign P22 seen, offering right and '
               'straight; the decision left is not on it' in text
               for text in comms.notes.texts()), comms.notes.texts()
    # Stopped just past the P22 (9 m along the tape, the truck set off 0.5 m along): the window,
    # 0.64 m ahead of the axle, saw the sign end without the left branch, within a metre.
    window_at = 0.5 + h.world.vehicle.state.distance + 0.64
    assert 9.0 < window_at < 10.0, window_at


# -- a room of one's own: agv-demo --truck concic2 --layout FILE --------------------------------

OWN_ROOM = straight_tape('own_room', 'two metres of straight tape', 2.0, 0.7)


@pytest.mark.timeout(120)
def test_agv_demo_takes_a_tape_layout_file_and_its_programme_runs_there(tmp_path, monkeypatch):
    from agv_nodes import demo
    from agv_nodes.harness import submit, truck

    room = tmp_path / 'own_room.yaml'
    room.write_text(OWN_ROOM)
    asked = []
    monkeypatch.setattr(demo, 'run', lambda args: asked.append(demo.programme(args)) or 0)
    assert demo.main(['--truck', 'concic2', '--layout', str(room)]) == 0
    assert asked == [(str(room), ['tape'])]
    # The programme on that floor in lock step: to the tape's end, completed.
    h = truck(str(room), overrides={'world': {'concic2.model': 'kinematic'}})
    h.run(0.5)
    for text in asked[0][1]:
        submit(h, text)
    ex = h.cores['executive']
    assert h.run(60.0, until=lambda: ex.mode in ('idle', 'failed') and ex.report['state']
                 in ('completed', 'failed'))
    assert ex.report['state'] == 'completed', ex.report


@pytest.mark.timeout(30)
def test_agv_demo_refuses_an_electruk_layout_for_the_camera_truck(capsys, monkeypatch) -> None:
    from agv_nodes import demo
    from agv_nodes.world.layout import layout_path

    monkeypatch.setattr(demo, 'run', lambda args: pytest.fail('ran'))
    room = str(layout_path('demo_1983'))
    assert demo.main(['--truck', 'concic2', '--layout', room]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and room in err[0] and 'electruk' in err[0] and 'concic2' in err[0], err
    with pytest.raises(SystemExit):  # the 1983 truck takes a layout only as a fleet's floor
        demo.main(['--layout', room])
