"""The 12 software channels at 50 ms, from a real recorded bag to CSV (Rajagopalan 1991, 6.3.8).

First in lock step: the channel log of a dual-camera leg (world, route following and a scripted
executive) names the law in operation and reads both cameras as the world places the tape.

A camera-truck graph over DDS (world, route following, executive, communications and the
recorder) drives a tape leg on junction_1991 and records its bag; `agv-report --channels BAG
--out FILE` writes the CSV. The header must be the thesis's list, in its order (6.3.8, written
out below apart from agv_nodes.channels), each row 50 ms of sim time after the last (App.
F.10: "The sampling interval is 50 ms") to within one /clock step, and the channels must say
what the ground truth and the records say.
"""

from __future__ import annotations

import csv
import math

from graph_probe import GraphProbe
import pytest

from agv_nodes.channels import NAMES, ChannelLog
from agv_nodes.harness import Harness
from agv_nodes.report import main as agv_report
from agv_nodes.route_following.core import RouteCore
from agv_nodes.route_following.dual_camera import Law
from agv_nodes.route_following.settings import RouteParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import Concic2Params, WorldNodeSettings, WorldParams

# Rajagopalan 1991, 6.3.8: "The data recorded by the software channels are
THESIS_ORDER = [
    'time_s',
    'desired_speed_left', 'desired_speed_right',  # "Desired wheel speeds read from the motion
    #                                                controllers."
    'controller_speed_left', 'controller_speed_right',  # "Actual wheel speeds read from the
    #                                                      motion controllers."
    'counted_speed_left', 'counted_speed_right',  # "Actual speed of the wheels." (7.5.2.1:
    #                                                from the position counts, slope method)
    'eps_df', 'eps_thetaf',  # "Position and orientation offsets from the front camera"
    'eps_dr', 'eps_thetar',  # "Position and orientation offsets from the rear camera"
    'steering_command',  # "Steering angle command based on camera information."
    'dual_law',  # "Control law in operation in dual camera mode."
]
PERIOD = 0.05  # s, App. F.10
CLOCK_STEP = WorldNodeSettings().clock_every / WorldParams().sample_rate  # s, /clock to /clock
CRUISE = 0.47  # m/s, route following's camera_speed


@pytest.mark.dds
@pytest.mark.slow
@pytest.mark.timeout(300)
def test_channels_csv_from_a_recorded_bag_has_the_thesis_order_every_50_ms(tmp_path) -> None:
    bag = tmp_path / 'bag'
    g = GraphProbe(tmp_path / 'logs', layout='junction_1991', bag=bag)
    try:
        g.start_task('tape for 2.0 m', cruise=0.3)
        g.report_with("'tape for 2.0 m': completed", wall_limit=120)
        # the leg's parking slow-down starts (0.47^2 - 0.16^2) / (2 * 0.25) + 0.05 + 0.005 =
        # 0.45 m before its length (route following's parameters): cruise until 1.5 m
        x0 = g.path[0][1]
        slowing = next(t for t, x, _y in g.path if x - x0 >= 1.5)
    finally:
        g.close()
    out = tmp_path / 'channels.csv'
    assert agv_report(['--channels', str(bag), '--out', str(out)]) == 0
    with out.open() as f:
        rows = list(csv.reader(f))
    assert rows[0] == THESIS_ORDER
    table = [[float(v) if v else math.nan for v in row] for row in rows[1:]]
    times = [row[0] for row in table]
    assert len(times) > 100  # the run is several seconds long
    # one row per 50 ms, none missed or doubled, each within a /clock step of the 50 ms grid
    # (the node's timer fires on the first /clock at or after it is due)
    ticks = [round((t - times[0]) / PERIOD) for t in times]
    assert ticks == list(range(len(times)))
    phase = sorted(t - k * PERIOD for t, k in zip(times, ticks, strict=True))
    assert phase[-1] - phase[0] <= 2 * CLOCK_STEP + 1e-6, (phase[0], phase[-1])
    # at cruise: what was asked, what the controllers and the counts say, all near the cruise
    col = {name: k for k, name in enumerate(THESIS_ORDER)}
    cruising = [r for r in table if r[col['controller_speed_left']] > CRUISE - 0.01
                and r[0] < slowing]
    assert len(cruising) > 20
    # the counted speed: whole mm counts over readings taken a /clock step either way of 50 ms
    counted_bound = (0.001 + CRUISE * 2 * CLOCK_STEP) / (PERIOD - 2 * CLOCK_STEP)
    for side in ('left', 'right'):
        counted = [r[col[f'counted_speed_{side}']] for r in cruising]
        assert abs(sum(counted) / len(counted) - CRUISE) < 0.01
        assert max(abs(v - CRUISE) for v in counted) <= counted_bound + 0.01
    for r in cruising:  # the steering's share of each wheel's demand is a few cm/s
        for name in ('desired_speed_left', 'desired_speed_right'):
            assert abs(r[col[name]] - CRUISE) < 0.05, (name, r)
        # the front window over the straight tape
        assert abs(r[col['eps_df']]) < 0.03 and abs(r[col['eps_thetaf']]) < 0.05, r
        # the rear one too, once it is past the tape's start (an empty cell before: no track):
        # logged though it does not steer (App. F.2 (8); a tape layout renders both cameras)
        assert math.isnan(r[col['eps_dr']]) or abs(r[col['eps_dr']]) < 0.03, r
        assert r[col['dual_law']] == 0.0  # the leading camera alone steers (cameras lead)
    assert sum(not math.isnan(r[col['eps_dr']]) for r in cruising) > 10
    assert agv_report(['--channels', str(tmp_path / 'logs'), '--out', str(out)]) == 2


class Exec:
    """A scripted executive: one camera leg forwards."""

    node, period = 'executive', 0.05

    def on_record(self, record, fields, now):
        pass

    def tick(self, now):
        return {'route_command': {'mode': 'camera', 'srm_angle': 0, 'junction': 'straight',
                                  'manoeuvre': 0, 'direction': 'forward', 'junction_number': 0,
                                  'junction_wait': 0, 'leg': 1}}


@pytest.mark.timeout(60)
def test_the_channel_log_of_a_dual_camera_leg_names_the_law_and_reads_both_cameras():
    assert ['time_s', *NAMES] == THESIS_ORDER
    world = WorldCore(load_layout(layout_path('junction_1991')),
                      WorldParams(seed=3, rear_camera=True,
                                  concic2=Concic2Params(model='kinematic')))
    route = RouteCore(RouteParams(vehicle='concic2', cameras='both'))
    h = Harness(world, [Exec(), route], seed=3)
    log, rows, seen, posed = ChannelLog(route.p.image), [], {}, {}
    st, due = world.vehicle.state, PERIOD
    while h.now < 6.0:  # to x = 2.3 m, short of the cross at 3 m
        h.step()
        for camera, frame in h.frames.items():
            if seen.get(camera) is not frame:  # the cameras' new frames, as the node takes them
                log.frame(frame, camera)
                seen[camera], posed[camera] = frame, (st.y, st.heading)
        if h.now >= due - 1e-9:
            rows.append(log.sample(route, h.now))
            due += PERIOD
    col = {name: k for k, name in enumerate(THESIS_ORDER)}
    # the rear window (L_c behind the axle) over the tape once the axle is 0.64 m past x = 0
    assert st.x - L_C > 0.3 and route.cam.law.law == 'dual'
    last = rows[-1]
    assert last[col['dual_law']] in {float(law.value) for law in Law}
    assert last[col['steering_command']] == route.cam.steer
    for camera, ahead, name in (('front', L_C, 'eps_df'), ('rear', -L_C, 'eps_dr')):
        y, heading = posed[camera]  # where the truck stood when the frame was taken
        window_y = y + ahead * math.sin(heading)  # the tape is y = 0
        # (the rear camera's frame is the frame of reverse travel: its left is the truck's right)
        assert last[col[name]] == pytest.approx(-window_y if ahead > 0 else window_y, abs=PIXEL)
    duals = [r for r in rows if r[col['dual_law']]]
    assert len(duals) > 20 and all(not math.isnan(r[col['eps_dr']]) for r in duals)
    before = [r for r in rows if math.isnan(r[col['eps_dr']])]  # rear window behind the start
    assert before and all(r[col['dual_law']] == 0.0 for r in before)


L_C = Concic2Params().camera_distance  # m, both windows from the axle (the world's)
PIXEL = RouteParams().image.width / 128  # m per column
