"""A frozen reader holds up neither its writer nor the writer's other readers.

A process of the graph can stop without dying: SIGSTOP, a debugger, a machine so loaded that
it is not scheduled for a while. Its writers' other readers must not notice. With Fast DDS's
shared-memory transport they did (bench/results/frozen_peer.md): on two busy cores, a writer at
340 Hz on four topics with one of its two readers frozen sent 820-1529 of 1700 samples in 5 s,
one publish once taking 2.0 s, against 1699-1700 with loopback UDP. The localhost profile
(config/dds/localhost_discovery.xml) therefore carries data over loopback UDP only; this test
runs bench/frozen_peer_bench.py with the profile the graph runs, the writer history of the
graph's stream writers (agv_nodes.qos.STREAM_WRITER), and both cores kept busy meanwhile. With
the shared-memory profile it fails (1529 sent of 1700 in the run that checked it).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from conftest import PYTHON, REPO

pytestmark = [pytest.mark.dds, pytest.mark.slow]
SECONDS = 5.0
HOG = 'import time\nend = time.monotonic() + {s}\nwhile time.monotonic() < end:\n    pass\n'


@pytest.mark.timeout(120)
def test_a_frozen_reader_holds_up_neither_its_writer_nor_the_other_reader():
    from agv_nodes import qos
    from agv_nodes.discovery import localhost_environment

    env = {**os.environ, **localhost_environment()}
    hogs = [subprocess.Popen([sys.executable, '-c', HOG.format(s=SECONDS + 20)])
            for _ in range(os.cpu_count() or 2)]
    try:
        res = subprocess.run([PYTHON, str(REPO / 'bench' / 'frozen_peer_bench.py'),
                              str(SECONDS), str(qos.STREAM_WRITER.depth)], env=env,
                             capture_output=True, text=True, timeout=90)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait(timeout=10)
    assert res.returncode == 0, res.stderr[-2000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    # Every round due at 340 Hz sent (one may fall past the end), none held up by the frozen
    # reader (a round of four publishes costs about 1 ms here; 50 ms is 17 rounds), and the
    # live reader received every one.
    assert got['sent'] >= got['due'] - 1, got
    assert got['worst_publish'] < 0.05, got
    assert got['received'] == got['sent'], got
