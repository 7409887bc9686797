"""A stand-in executive written from the docs alone drives the launched truck over DDS.

The graph runs without its executive (a graph file without it, `agv-launch --graph`); the
stand-in (test/standin_executive.py, its own process) packs its records from msg_schemas/ and
is admitted through the readers' `record_writers`, as docs/hardware.md walks through. It starts
with the graph, before traction's reader can have matched it (its first 00H may be lost: the
start-up contract must carry it through), drives at a demand and stops with 00H. What happened
is read from the world's ground truth (world/pose, world/events), never from the stand-in.

The first test checks, without DDS, that the stand-in's packing agrees with the package's codec
both ways: a stand-in that packed wrongly would be refused, not admitted.
"""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys
import threading

import pytest
import yaml

from agv_nodes.package_share import config_dir
from agv_nodes.records.codec import codec
from agv_nodes.records.ports import RecordWriter
from agv_nodes.settings import settings_from_file
from agv_nodes.traction.settings import TractionParams

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import standin_executive  # noqa: E402  (test/ is not a package)

NAME = standin_executive.NAME
DEMAND = 30  # % duty
DRIVE = 6.0  # sim s at the demand
AT_REST = 0.005  # m/s, as test/graph_probe.py
STOP_WITHIN = 0.2  # s from the 00H to the drive off (the e-stop's budget in docs/faults.md)


def graph_without_executive(tmp_path: Path) -> Path:
    """Write config/graph.yaml without its executive (and its own parameter file) to tmp_path."""
    source = config_dir() / 'graph.yaml'
    doc = yaml.safe_load(source.read_text())
    doc['nodes'] = [n for n in doc['nodes'] if n['name'] != 'executive']
    doc['parameters'] = str(source.parent / doc['parameters'])
    out = tmp_path / 'graph_without_executive.yaml'
    out.write_text(yaml.safe_dump(doc))
    return out


@pytest.mark.timeout(30)
def test_the_stand_ins_records_are_the_codecs():
    c = codec()
    for record, values in (('traction_command', {'demand': -30, 'executive_priority': 1}),
                           ('traction_command', {'demand': 0}),
                           ('route_command', {'mode': 'follow_wire', 'direction': 'reverse'})):
        raw = standin_executive.Table(record).pack(values)
        assert c[record].decode(raw, integrity='e2e').items() >= values.items()
    status = {'ref': -5, 'duty': -12, 'emergency_stop': 1, 'radio_stop': 0, 'bumper': 1,
              'tripped': 1, 'manual': 0, 'field_forward': 0, 'armature_on': 0, 'reversing': 1,
              'source': 'trip', 'trip_cause': 'startup', 'speed': -1234}
    raw = RecordWriter(c['traction_status'], 'e2e').pack(status)
    assert standin_executive.Table('traction_status').unpack(raw) == status
    assert standin_executive.Table('traction_status').unpack(raw[:15] + bytes([raw[15] ^ 1])) \
        is None  # a bad CRC is refused


class Lines:
    """The stand-in's stdout, read as it comes: 'standin: <what> at <t>' -> t."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.all: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._thread.start()

    def _read(self, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            self.all.append(line.rstrip())

    def at(self, what: str) -> float | None:
        """Return the sim time of the first line `standin: <what> at T` (None: not yet)."""
        for line in list(self.all):
            head, sep, t = line.rpartition(' at ')
            if sep and head == f'standin: {what}':
                return float(t)
        return None


@pytest.mark.dds
@pytest.mark.slow
@pytest.mark.timeout(420)
def test_a_stand_in_executive_from_the_docs_starts_drives_and_stops_the_truck(tmp_path):
    from graph_probe import GraphProbe

    from agv_nodes.graph.model import load_graph
    from agv_nodes.graph.parameters import Options, paced_nodes

    graph = graph_without_executive(tmp_path)
    paced = [*paced_nodes(load_graph(graph), Options(graph=graph)), NAME]
    g = GraphProbe(tmp_path, graph=graph, extra={
        'traction': [f"record_writers:=['traction_command={NAME}']"],
        'route_following': [f"record_writers:=['route_command={NAME}']"],
        'world': [f'pace_nodes:={paced}']})
    proc = subprocess.Popen(
        [sys.executable, str(HERE / 'standin_executive.py'), '--demand', str(DEMAND),
         '--drive', str(DRIVE), '--ros-args', '-p', 'use_sim_time:=true'],
        env={**os.environ, 'ROS_DOMAIN_ID': str(g.launch.domain)}, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    lines = Lines(proc)
    try:
        g.spin_until(lambda: lines.at('stop (00H)') is not None or proc.poll() is not None,
                     300, 'the stand-in to start the truck, drive it and send its stop')
        assert proc.poll() is None, lines.all
        closed, stop = lines.at('relay closed'), lines.at('stop (00H)')
        assert closed is not None and stop is not None, lines.all
        taken = [line for line in lines.all if line.startswith('standin: 00H taken')]
        assert taken and float(taken[0].rpartition(' at ')[2]) <= closed, lines.all
        print(*lines.all[:4], sep='\n')  # how many 00H records the start took, and when
        g.spin_until(lambda: g.time > stop + 1.0, 60, 'a second after the stop')
        rest_from = g.stays_at_rest(hold=2.0, wall_limit=120, what='the truck at rest')
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
        g.close()

    # moved as demanded: the closed loop's speed for the demand, from traction's parameters
    # (v = (demand - dead_band) * v_per_percent, thesis 6.3.2's open-loop map)
    p = settings_from_file(TractionParams, config_dir() / 'agv_demo.yaml', 'traction')
    target = (DEMAND - p.dead_band) * p.v_per_percent
    window = [(t, x, y) for t, x, y in g.path if stop - 2.0 <= t <= stop]
    assert len(window) > 10, 'no ground truth in the last 2 s before the stop'
    (t0, x0, y0), (t1, x1, y1) = window[0], window[-1]
    cruise = ((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5 / (t1 - t0)
    assert abs(cruise - target) <= 0.05 * target, (cruise, target)
    assert g.travelled_since(closed) > 0.5 * target * DRIVE
    # stopped as demanded: the drive off within the e-stop's budget, at rest, stays at rest
    g.drive_off_ms(stop, STOP_WITHIN)
    assert stop <= rest_from <= stop + 2.0, (stop, rest_from)
    # every record of the stand-in's that traction took was its own, none refused as foreign
    values = g.inputs['traction']
    assert int(values['traction_command accepted']) > 0
    assert 'foreign_writer' not in values['traction_command rejects by reason'], values
    assert set(g.trips) <= {'startup'}, g.trips  # no trip but the start-up one it cleared
