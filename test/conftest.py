"""Test-session set-up: a ROS domain of our own, localhost discovery, hypothesis profiles.

Same-host graphs on one ROS_DOMAIN_ID cross-talk even with localhost-only discovery
(anchors.md section 7), so the session claims a free domain id 1-232 with an exclusive lock
file before anything touches rclpy, and every child process inherits it. Domain 0 is never used.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import sys

from hypothesis import HealthCheck, settings

REPO = Path(__file__).resolve().parent.parent
_LOCK_DIR = Path(os.environ.get('AGV_DOMAIN_LOCK_DIR', '/tmp'))
_held = []


def _claim_domain() -> int:
    start = 1 + os.getpid() % 200
    for i in range(232):
        domain = 1 + (start + i - 1) % 232
        handle = open(_LOCK_DIR / f'agv_nodes_ros_domain_{domain}.lock', 'w')  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _held.append(handle)  # keep the lock for the whole session
        return domain
    raise RuntimeError('no free ROS domain id 1-232 on this host')


if 'AGV_TEST_DOMAIN' in os.environ:
    os.environ['ROS_DOMAIN_ID'] = os.environ['AGV_TEST_DOMAIN']
else:
    os.environ['ROS_DOMAIN_ID'] = str(_claim_domain())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('PYTHONUNBUFFERED', '1')
assert os.environ['ROS_DOMAIN_ID'] != '0', 'tests must never use ROS domain 0'

settings.register_profile('ci', max_examples=150, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile('long', max_examples=5000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get('AGV_HYPOTHESIS_PROFILE', 'ci'))

# The venv's own python must start node processes (it re-executes itself to set
# LD_LIBRARY_PATH for the ROS wheels; anchors.md section 8).
PYTHON = sys.executable
