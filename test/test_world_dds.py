"""Real DDS: the world node in its own process, driven by a test publisher in another."""

from __future__ import annotations

import json
from pathlib import Path
import subprocess

import pytest

from conftest import PYTHON, REPO

pytestmark = pytest.mark.dds
WORLD = str(Path(PYTHON).parent / 'world')


def test_world_node_publishes_adc_at_340_hz_of_sim_time():
    seconds = 4.0
    world = subprocess.Popen(
        [WORLD, '--ros-args', '-p', 'layout:=straight_track', '-p', 'time_factor:=2.0',
         '-p', f'duration:={seconds + 1.0}',
         '-p', 'wait_for_subscribers:=[hw/position_sensor/adc]',
         '-p', 'wait_for_publishers:=[hw/traction/drive]'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    probe = subprocess.run([PYTHON, str(REPO / 'test' / 'world_probe.py'), str(seconds), '60'],
                           capture_output=True, text=True, timeout=120)
    out, _ = world.communicate(timeout=60)
    assert probe.returncode == 0, probe.stderr
    assert world.returncode == 0, out
    state = json.loads(probe.stdout.strip().splitlines()[-1])
    elapsed = state['clock']
    assert elapsed >= seconds
    rate = state['adc'] / elapsed
    assert rate == pytest.approx(340.0, rel=0.01), state
    assert state['speed'] > 300  # the test publisher's drive record moved the truck (mm/s)
