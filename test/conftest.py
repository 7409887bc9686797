"""Test-session set-up: a ROS domain of our own, localhost discovery, hypothesis profiles.

Same-host graphs on one ROS_DOMAIN_ID cross-talk even with localhost-only discovery
(measured), so the session claims a free domain id 1-232 with an exclusive lock
file before anything touches rclpy, and every child process inherits it. Domain 0 is never used.
"""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path
import sys
import tempfile

from hypothesis import HealthCheck, settings
import pytest

from agv_nodes.discovery import use_localhost_discovery

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
use_localhost_discovery()  # before any participant of this process
os.environ.setdefault('PYTHONUNBUFFERED', '1')
assert os.environ['ROS_DOMAIN_ID'] != '0', 'tests must never use ROS domain 0'

settings.register_profile('ci', max_examples=150, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile('long', max_examples=5000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get('AGV_HYPOTHESIS_PROFILE', 'ci'))

# The venv's own python must start node processes (it re-executes itself to set
# LD_LIBRARY_PATH for the ROS wheels).
PYTHON = sys.executable


# -- lanes for pytest-xdist -----------------------------------------------------------------------
# `AGV_TEST_WORKERS=2 ./agv.sh test` runs two workers (`-n 2 --dist loadgroup
# --no-loadscope-reorder`; the default is one process, as fast on two cores). A graph over
# DDS keeps 1.5-1.9 of the machine's two cores busy and misses its records when it is starved,
# so the tests marked `dds` or `wall_clock` run one at a time, first, in one lane of their own at
# full priority. The others, lock-step simulations that only need CPU, run in the second lane at
# the lowest priority (nice 19): on the CPU the first lane leaves, so their time limits are
# BACKGROUND_LIMITS times their own. Each module of the second lane stays on one worker, so its
# module fixtures run once.
FIRST_LANE = 'first_lane'
BACKGROUND_LIMITS = 4


def _lane(item) -> str:
    if item.get_closest_marker('dds') or item.get_closest_marker('wall_clock'):
        return FIRST_LANE
    return item.nodeid.split('::')[0]


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist's own: it names the groups
def pytest_collection_modifyitems(config, items) -> None:
    if not hasattr(config, 'workerinput'):  # not a pytest-xdist worker: one process, as it is
        return
    items.sort(key=lambda item: _lane(item) != FIRST_LANE)  # stable: the first lane first
    for item in items:
        lane = _lane(item)
        item.add_marker(pytest.mark.xdist_group(lane))
        _name_group(item, lane)
        limit = item.get_closest_marker('timeout')
        if lane != FIRST_LANE and limit is not None:
            seconds = limit.args[0] if limit.args else limit.kwargs['timeout']
            item.add_marker(pytest.mark.timeout(seconds * BACKGROUND_LIMITS), append=False)


def _name_group(item, lane: str) -> None:
    """Suffix the item's id with its group, which is how the scheduler sees groups.

    pytest-xdist 3.8 does it by setting `item._nodeid`, which pytest 9 no longer reads (its ids
    are NodeId objects in `item._id`); on an older pytest, xdist's own hook does it.
    """
    try:
        from _pytest.nodeid import NodeId
    except ImportError:  # pytest < 9
        return
    item._id = NodeId.parse(f'{item.nodeid}@{lane}')


_in_background = False


def pytest_runtest_setup(item) -> None:
    global _in_background
    _fault_table.test = f'{Path(item.fspath).name}::{item.name}'
    if hasattr(item.config, 'workerinput') and _lane(item) != FIRST_LANE and not _in_background:
        os.nice(19)  # for good: the first lane's tests all come before (one work unit)
        _in_background = True


# -- the fault table: every fault test that passes adds its row ---------------------------------
# A test's rows wait until its teardown has passed too, then join the session's table. Each
# session writes its own results file outside the repository (tests never write tracked files),
# named with its pid in the temporary directory unless `AGV_FAULT_RESULTS` names one (not under
# basetemp: pytest deletes all but the last three sessions' of those, other users' included),
# and says where at the end; a partial run cannot overwrite another's. `python
# test/fault_table.py --results FILE` turns a full run's rows into docs/faults.md.


class FaultTable:
    """Rows (fault, expected, observed, test) collected during the session."""

    def __init__(self) -> None:
        self.rows: dict[str, tuple[str, str, str]] = {}
        self.test = ''
        self.pending: list[tuple[str, tuple[str, str, str]]] = []  # the running test's rows
        self.spoiled = False  # a phase of the running test failed or skipped: its rows go

    def add(self, fault: str, expected: str, observed: str) -> None:
        """Record a fault the current test tried, once its assertions have passed."""
        self.pending.append((fault, (expected, observed, self.test)))

    def start(self) -> None:
        """Begin a test: nothing of it is in the table yet."""
        self.pending, self.spoiled = [], False

    def settle(self, report) -> None:
        """Take one phase's report; commit the test's rows once its teardown passed too."""
        if not report.passed:
            self.spoiled = True
        if report.when == 'teardown':
            if not self.spoiled:
                self.rows.update(self.pending)
            self.pending = []


_fault_table = FaultTable()


def pytest_runtest_logstart(nodeid, location) -> None:
    _fault_table.start()


def pytest_runtest_logreport(report) -> None:
    # a pytest-xdist controller sees its workers' reports too, with nothing pending of its own
    _fault_table.settle(report)


def fault_results(config) -> Path:
    """Return the session's own results file (AGV_FAULT_RESULTS, else named with its pid)."""
    if 'AGV_FAULT_RESULTS' in os.environ:
        return Path(os.environ['AGV_FAULT_RESULTS'])
    return Path(tempfile.gettempdir()) / f'agv_nodes_fault_rows.{os.getpid()}.json'


def pytest_sessionfinish(session, exitstatus) -> None:
    workeroutput = getattr(session.config, 'workeroutput', None)
    if workeroutput is not None:  # a pytest-xdist worker: its rows go to the controller
        workeroutput['fault_rows'] = json.dumps(_fault_table.rows)
        return
    if not _fault_table.rows:
        return
    fault_results(session.config).write_text(json.dumps({
        'tests_collected': session.testscollected, 'tests_failed': session.testsfailed,
        'rows': {fault: list(row) for fault, row in sorted(_fault_table.rows.items())}},
        indent=1))


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    if _fault_table.rows and not hasattr(config, 'workerinput'):
        terminalreporter.write_line(f'fault table: {len(_fault_table.rows)} rows in '
                                    f'{fault_results(config)} (test/fault_table.py --results)')


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error) -> None:
    """Take a finished pytest-xdist worker's fault rows (the controller writes the file)."""
    rows = getattr(node, 'workeroutput', {}).get('fault_rows')
    if rows:
        _fault_table.rows.update({fault: tuple(row) for fault, row in json.loads(rows).items()})


@pytest.fixture
def fault_table() -> FaultTable:
    """Return the session's fault table (test/fault_table.py makes docs/faults.md of it)."""
    return _fault_table
