"""Real DDS: two rclpy processes exchange a navigation_status record on its topic."""

from __future__ import annotations

import json
import os
import signal
import subprocess

import pytest

from agv_nodes.records import codec

from conftest import PYTHON, REPO

pytestmark = pytest.mark.dds
PEER = str(REPO / 'test' / 'dds_peer.py')


def test_two_processes_exchange_navigation_status():
    assert os.environ['ROS_DOMAIN_ID'] not in ('', '0')
    echo = subprocess.Popen([PYTHON, PEER, 'echo', 'navigation_status', '3'],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pub = subprocess.Popen([PYTHON, PEER, 'pub', 'navigation_status', 'at_location=1',
                            'slow=1', 'lost=0', 'last_marker=2'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        out, err = echo.communicate(timeout=60)
    finally:
        pub.send_signal(signal.SIGINT)
        pub.wait(timeout=20)
    assert echo.returncode == 0, err
    # Fast DDS logs on the same stdout (e.g. a shared-memory port a SIGKILLed process left
    # locked, which it then skips): only the peer's lines are JSON objects.
    lines = [json.loads(line) for line in out.splitlines() if line.startswith('{')]
    assert len(lines) == 3
    for line in lines:
        raw = bytes.fromhex(line['raw'])
        assert len(raw) == 16 and raw[:3] == bytes([0x03, 0x02, 0x00])  # positioning at 2
        assert line['fields'] == codec().decode('navigation_status', raw)
    counters = [bytes.fromhex(line['raw'])[14] for line in lines]
    assert counters == sorted(counters) and len(set(counters)) == 3  # E2E counter advancing
    assert pub.returncode == 0, pub.stderr.read()
