"""A flood of tasks over DDS: every task sent is queued, refused with a line, or counted lost.

The communications node runs alone (its own process, wall-clock time: it needs no world to
queue tasks, and with no executive nothing leaves the queue, so exactly `max_queue` are
queued). A probe node in the test sends tasks on comms/task as a task-sending program would (a
reliable writer keeping the last 10, as docs/tasks.md's example) and reads comms/report with
a reader that keeps all and /diagnostics.

1. Running: N tasks in one burst, every 40th of them longer than `max_task_length` (the
   parameter file's default), each of its own length so that its line names it, and one of
   1 MiB. Then `status` until answered: communications takes a writer's messages in order, so
   every earlier one has been handled, and a gap in the writer's sequence numbers before the
   status has been counted.
2. Frozen: communications is SIGSTOPped, M more tasks are sent, and it is woken. What it can
   still take is what its reader's history (qos.TASKS, 256) and the writer's (10) kept; the
   rest is lost on the way (measured: 256 of 400 taken), so the count of lost messages is
   exercised whatever the machine's speed. The test asks for all but twice the histories.

After each phase: the queued lines and refused lines name disjoint tasks of those sent, in the
order sent, a refused line per refusal (too long lines give the length and the limit and
never the text), and the sum queued + refused + lost equals the tasks sent exactly; the
/diagnostics row `agv/<ns>/communications/tasks` shows the same counts.
"""

from __future__ import annotations

import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import time

import pytest

from agv_nodes import qos
from agv_nodes.communications.core import CommsParams

pytestmark = [pytest.mark.dds, pytest.mark.timeout(240)]

COMMUNICATIONS = str(Path(sys.executable).parent / 'communications')
MAX_QUEUE = 8  # set by the test (-p max_queue): well below the flood
WRITER_DEPTH = 10
N_RUNNING = 400
N_FROZEN = 1000
TOO_LONG = CommsParams().max_task_length  # the parameter file's default
MIB = 1 << 20
_REFUSED_LONG = re.compile(r'^comms: refused a task of (\d+) characters \(more than '
                           r'max_task_length (\d+)\)$')
_REFUSED_FULL = re.compile(r"^comms: refused '(.*)': queue full \((\d+) tasks, "
                           r'max_queue (\d+)\)$')
_QUEUED = re.compile(r"^task (\d+) queued: '(.*)' \((\d+) in queue\)$")


def _task(i: int) -> str:
    """Return the i-th task of the flood: a text of its own; every 40th too long (by i)."""
    if i % 40 == 39:
        return f'stop at 2 first{" " * (TOO_LONG + i)}'  # parses, but too long to be read
    return f'wait at {i % 4} for {i // 4} s'  # i < 1024: unique


class Flood:
    """The communications process and the probe's ends of its topics."""

    def __init__(self, tmp_path: Path) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import String

        self.ns = f'flood{os.getpid()}'
        self.log = open(tmp_path / 'communications.log', 'w+')  # noqa: SIM115 - read at the end
        self.proc = subprocess.Popen(
            [COMMUNICATIONS, '--ros-args', '-r', f'__ns:=/{self.ns}', '-p',
             'use_sim_time:=false', '-p', f'max_queue:={MAX_QUEUE}'],
            stdout=self.log, stderr=subprocess.STDOUT, text=True)
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('flood_probe', namespace=self.ns, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.lines: list[str] = []
        self.rows: list[tuple[int, dict[str, str]]] = []
        self.task_pub = self.node.create_publisher(
            String, 'comms/task', QoSProfile(depth=WRITER_DEPTH,
                                             reliability=ReliabilityPolicy.RELIABLE))
        self.node.create_subscription(
            String, 'comms/report', lambda m: self.lines.append(m.data),
            QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._row, qos.EVENTS)
        self.String = String

    def _row(self, msg) -> None:
        for s in msg.status:
            if s.name == f'agv/{self.ns}/communications/tasks':
                self.rows.append((int.from_bytes(s.level, 'little'),
                                  {kv.key: kv.value for kv in s.values}))

    def said(self) -> str:
        self.log.seek(0)
        return self.log.read()[-3000:]

    def spin_until(self, condition, wall_limit: float, what: str) -> None:
        deadline = time.monotonic() + wall_limit
        while not condition():
            assert self.proc.poll() is None, f'communications ended: {self.said()}'
            assert time.monotonic() < deadline, f'{what}: not within {wall_limit} s'
            self.executor.spin_once(timeout_sec=0.05)

    def send(self, text: str) -> None:
        self.task_pub.publish(self.String(data=text))

    def answers(self) -> int:
        return sum(line.startswith('comms: status:') for line in self.lines)

    def status(self, wall_limit: float = 30) -> None:
        """Send `status` until answered: everything sent before has been handled."""
        before = self.answers()
        deadline = time.monotonic() + wall_limit
        while True:
            self.send('status')
            turn = time.monotonic() + 0.5
            while time.monotonic() < turn:
                if self.answers() > before:
                    return
                assert self.proc.poll() is None, f'communications ended: {self.said()}'
                self.executor.spin_once(timeout_sec=0.05)
            assert time.monotonic() < deadline, f'no status answer: {self.said()}'

    def row_after(self, count: int, wall_limit: float = 10) -> dict[str, str]:
        """Return the values of the latest tasks row once `count` more rows have come."""
        start = len(self.rows)
        self.spin_until(lambda: len(self.rows) >= start + count, wall_limit, 'a tasks row')
        return self.rows[-1][1]

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGCONT)
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        self.node.destroy_node()
        import rclpy

        rclpy.try_shutdown(context=self.context)
        self.log.close()


def account(lines: list[str], sent: list[str]) -> tuple[list[str], list[str], list[int]]:
    """(texts queued, texts refused for a full queue, lengths refused as too long) from lines."""
    queued, full, long = [], [], []
    for line in lines:
        if m := _QUEUED.match(line):
            queued.append(m[2])
        elif m := _REFUSED_FULL.match(line):
            assert (int(m[2]), int(m[3])) == (MAX_QUEUE, MAX_QUEUE), line
            full.append(m[1])
        elif m := _REFUSED_LONG.match(line):
            assert int(m[2]) == TOO_LONG and len(line) < 100, line
            long.append(int(m[1]))
    # each names a task sent, and no task twice (a text, or a too-long task's length)
    lengths = [len(t) for t in sent]
    assert all(t in sent for t in queued + full), 'a line names a task not sent'
    assert all(lengths.count(n) == 1 for n in long), 'a refused length names no task sent'
    named = queued + full + [sent[lengths.index(n)] for n in long]
    assert len(named) == len(set(named)), 'a task named twice'
    return queued, full, long


def test_a_flood_of_tasks_is_accounted_for_exactly(tmp_path):
    flood = Flood(tmp_path)
    try:
        flood.status(wall_limit=60)  # both ends matched: communications answers
        first = len(flood.lines)
        sent = [_task(i) for i in range(N_RUNNING)]
        sent[N_RUNNING // 2] = 'stop at 2 first' + ' ' * (MIB - 15)  # a 1 MiB task
        for text in sent:
            flood.send(text)
        flood.status()
        lines = flood.lines[first:]
        assert not any(len(line) > 200 for line in lines), 'a line echoes a long task'
        queued, full, long = account(lines, sent)
        assert queued == [t for t in sent if t in set(queued)]  # in the order sent
        assert full == [t for t in sent if t in set(full)]
        assert len(queued) == MAX_QUEUE  # nothing leaves the queue: no executive runs
        row = flood.row_after(2)  # sent after the status answer: the counts include it
        lost = int(row['lost'])
        assert len(queued) + len(full) + len(long) + lost == N_RUNNING, (row, len(full))
        assert (int(row['queued']), int(row['refused queue full']),
                int(row['refused too long'])) == (len(queued), len(full), len(long)), row
        assert int(row['in queue']) == MAX_QUEUE and row['max_queue'] == str(MAX_QUEUE)
        # every too-long task that reached communications was refused as such, none queued
        assert all(len(sent[k]) > TOO_LONG for k in range(N_RUNNING) if len(sent[k]) in long)
        assert not [t for t in queued + full if len(t) > TOO_LONG]

        # 2. communications frozen: most are lost on the way (the histories keep 256 + 10)
        first = len(flood.lines)
        flood.proc.send_signal(signal.SIGSTOP)
        frozen = [f'wait at {i % 4} for {i // 4} s first' for i in range(N_FROZEN)]
        for text in frozen:
            flood.send(text)
        time.sleep(0.5)  # the writer's history overflows meanwhile
        flood.proc.send_signal(signal.SIGCONT)
        flood.status()
        _, full2, long2 = account(flood.lines[first:], frozen)
        row2 = flood.row_after(2)
        lost2 = int(row2['lost']) - lost
        assert not long2 and int(row2['queued']) == MAX_QUEUE
        assert len(full2) + lost2 == N_FROZEN, (row2, len(full2))
        assert lost2 >= N_FROZEN - 2 * (qos.TASKS.depth + WRITER_DEPTH), row2
        assert int(row2['refused queue full']) == len(full) + len(full2), row2
        levels = [level for level, _ in flood.rows]
        assert 1 in levels, 'no WARN while tasks were refused and lost'
        said_lost = [int(m[1]) for line in flood.lines
                     if (m := re.match(r'^comms: (\d+) task messages lost', line))]
        assert sum(said_lost) == int(row2['lost']), 'the lost lines do not add up'
    finally:
        flood.close()
