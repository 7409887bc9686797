"""A test's window on the whole graph over DDS: launch it, drive it, watch the ground truth.

Used by the fault tests (test_kill_dds.py, test_faults_dds.py). The probe is an rclpy node in
the test process on the graph's own ROS domain: it sends tasks, pauses the world to do
something at an exact simulated time, switches world faults at run time (parameters), and
keeps the world's ground truth: speed from /world/pose, drive_off and other events from
world/events (stamped in sim time), reports, traction trips and /diagnostics errors.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

AT_REST = 0.005  # m/s
CRUISE = 0.6  # m/s the truck must exceed before a fault (1983 cruise: 0.7)
# mm from the stop marker's centre a controlled stop over DDS ends within (the README's claim);
# the 1983 friction stop rolls +34..+55 mm, so a fall-back to it fails.
STOP_TOLERANCE_MM = 15


def event_time(time_ms: int, reference: float) -> float:
    """Unwrap a world_event's 16-bit ms stamp to the sim time nearest `reference`.

    The result is within 32.8 s of `reference` either way. The reference is the probe's last
    pose, and the probe's single-threaded executor takes one pose per turn: after a busy
    start-up its poses can run over 1 s behind a fresh event. A window of at most 1 s ahead of
    the pose would then put W2.1's passage 65.5 s in the past, and the route-limit test would
    measure the whole run instead of the 4 m past W2.1.
    """
    ref_ms = round(reference * 1000)
    return (ref_ms + (time_ms - ref_ms + 32768) % 65536 - 32768) / 1000


class GraphProbe:
    """The launched graph plus a probe node; `close()` shuts both down."""

    def __init__(self, log_dir, **options: Any) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import PoseStamped
        import rclpy
        from rclpy.context import Context
        from std_msgs.msg import Bool, String
        from std_srvs.srv import Trigger

        from agv_nodes import qos
        from agv_nodes.graph.parameters import Options
        from agv_nodes.graph.supervisor import Launch
        from agv_nodes.records.codec import codec
        from agv_nodes.ros_ports import RecordSubscription

        # as fast as the graph holds unless the test says otherwise (time_factor=...)
        self.launch = Launch(Options(**{'time_factor': 0.0, 'quiet': True, 'log_dir': log_dir,
                                        'domain_id': int(os.environ['ROS_DOMAIN_ID']),
                                        **options}))
        self.context = Context()
        rclpy.init(context=self.context, domain_id=self.launch.domain)
        self.node = rclpy.create_node('fault_probe', context=self.context)
        self.executor = rclpy.executors.SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.speed = 0.0
        self.time = 0.0  # sim time of the last pose
        self._last: tuple[float, float, float] | None = None
        self.path: list[tuple[float, float, float]] = []  # (sim t, x, y) at 50 Hz
        self.reports: list[str] = []
        self.trips: list[str] = []
        self.events: list[tuple[float, dict]] = []
        self.errors: dict[str, str] = {}  # /diagnostics label -> message, level ERROR
        self.inputs: dict[str, dict[str, str]] = {}  # node -> its /diagnostics inputs values
        self.expected_dead: set[str] = set()
        self._timeline = None  # SentTimeline once a record is watched for its send time
        self._sent: dict[str, list] = {}  # watched record's unique name -> [sent, fields]
        n = self.node
        n.create_subscription(PoseStamped, 'world/pose', self._pose, qos.STREAM_READER)
        n.create_subscription(String, 'comms/report', lambda m: self.reports.append(m.data),
                              qos.EVENTS)
        n.create_subscription(DiagnosticArray, '/diagnostics', self._diagnostics, qos.EVENTS)
        self._subs = [
            RecordSubscription(n, codec()['traction_status'], 'e2e', self._traction),
            RecordSubscription(n, codec()['world_event'], 'e2e', self._event)]
        self.task_pub = n.create_publisher(String, 'comms/task', qos.EVENTS)
        # the radio receiver's driver: the radio stop's named writer (settings.SWITCH_WRITERS)
        self.radio_node = rclpy.create_node('radio_receiver', context=self.context)
        self.radio_pub = self.radio_node.create_publisher(Bool, 'hw/radio_stop',
                                                          qos.RECORD_WRITER)
        self._pause = n.create_client(Trigger, 'world/pause')
        self._resume = n.create_client(Trigger, 'world/resume')
        self.launch.start()

    # -- callbacks --------------------------------------------------------------------------
    def _pose(self, msg) -> None:
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        x, y = msg.pose.position.x, msg.pose.position.y
        if self._last is not None and t > self._last[0]:
            self.speed = math.hypot(x - self._last[1], y - self._last[2]) / (t - self._last[0])
        self._last, self.time = (t, x, y), t
        self.path.append((t, x, y))

    def _traction(self, fields: dict) -> None:
        if fields['tripped']:
            self.trips.append(fields['trip_cause'])

    def _event(self, fields: dict) -> None:
        self.events.append((event_time(fields['time_ms'], self.time), fields))

    def _diagnostics(self, msg) -> None:
        for st in msg.status:
            level = st.level if isinstance(st.level, int) else int.from_bytes(st.level, 'little')
            label = st.name.split('/', 1)[1]  # 'agv/traction' -> traction, traction/inputs
            if level == 2:
                self.errors[label] = st.message
            if label.endswith('/inputs'):
                self.inputs[st.hardware_id] = {kv.key: kv.value for kv in st.values}

    def watch_sent(self, record: str) -> list[list]:
        """Keep each `record` the probe takes as [sim time it was sent at, fields], in order.

        The send time is the world's sim time when the writer sent it, from its DDS source
        timestamp against the world's /clock samples (agv_nodes/sent_time.py, as the executive
        ages statuses): the latest clock sample sent before it, so exact to one clock step.
        """
        from rosgraph_msgs.msg import Clock

        from agv_nodes import qos
        from agv_nodes.records.codec import codec
        from agv_nodes.ros_ports import RecordSubscription
        from agv_nodes.sent_time import SentTimeline

        if self._timeline is None:
            self._timeline = SentTimeline()
            self.node.create_subscription(Clock, '/clock', self._clock, qos.CLOCK_READER)
        kept: list[list] = []
        sub: list[RecordSubscription] = []

        def take(fields: dict) -> None:
            name = f'{record}#{len(self._sent)}'  # each its own: a later one must not replace it
            kept.append([self._timeline.record(name, sub[0].sent_ns), fields])
            self._sent[name] = kept[-1]
        sub.append(RecordSubscription(self.node, codec()[record], 'e2e', take, sent_stamps=True))
        self._subs.append(sub[0])
        return kept

    def _clock(self, msg, info: dict) -> None:
        sim = msg.clock.sec + msg.clock.nanosec * 1e-9
        for name, sent in self._timeline.clock(info.get('source_timestamp') or 0, sim):
            self._sent[name][0] = sent  # sent after the sample it had: raised as they come

    def last_sent_before(self, kept: list[list], t: float) -> float:
        """Sim time the last of `kept` sent at or before `t` was sent at."""
        before = [sent for sent, _fields in kept if sent <= t + 1e-9]
        assert before, f'none sent before {t:.3f} s: {[round(k[0], 3) for k in kept[-5:]]}'
        return before[-1]

    def settings(self, node: str, cls: type) -> Any:
        """Return the settings `node` runs with in this launch, as declared (not asked of it).

        The class's declared defaults (agv_nodes/<node>/parameters.yaml), the launch's parameter
        file over them (config/agv_demo.yaml), then what the launch sets on top: what the node
        is told, so that a node not doing as told fails the test.
        """
        from agv_nodes.graph.parameters import override_parameters
        from agv_nodes.settings import parameter_file_values, parameters, settings_from_file

        spec = next(s for s in self.launch.specs() if s.name == node)
        known = {p.name for p in parameters(cls)}
        given = override_parameters(self.launch.graph, spec, self.launch.o)
        _shared, own = parameter_file_values(self.launch.params, node)
        return settings_from_file(cls, self.launch.params, node,
                                  {k: v for k, v in given.items() if k in known},
                                  also_known=frozenset(own) - known)

    def accepted(self) -> dict[str, dict[str, int]]:
        """Node -> record -> records accepted, from the latest /diagnostics inputs rows."""
        from agv_nodes.demo import accepted_counts

        return {node: accepted_counts(values) for node, values in self.inputs.items()}

    # -- driving ----------------------------------------------------------------------------
    def counted(self, node: str, key: str) -> int:
        """Return a count from `node`'s latest /diagnostics inputs row (0 before it has one)."""
        return int(self.inputs.get(node, {}).get(key, '0'))

    def spin_until(self, condition, wall_limit: float, what: str) -> None:
        """Spin until `condition()`; fail on a timeout or an unexpected dead node."""
        deadline = time.monotonic() + wall_limit
        while not condition():
            self.executor.spin_once(timeout_sec=0.05)
            dead = [n for n in self.launch.poll() if n not in self.expected_dead]
            assert not dead, f'{dead} died while waiting for {what}'
            assert time.monotonic() < deadline, (
                f'timed out waiting for {what}; reports {self.reports}; '
                + '\n'.join(self.launch.lines[-40:]))

    def start_task(self, text: str, cruise: float | None = CRUISE) -> None:
        """Wait for the graph, send a task, and (optionally) wait until it runs at speed."""
        from std_msgs.msg import String

        self.ready()
        self.task_pub.publish(String(data=text))
        if cruise is not None:
            self.spin_until(lambda: self.speed > cruise, 90, f'the truck to exceed {cruise}')

    def ready(self) -> None:
        """Wait until the world moves, communications answers and every link carried a record."""
        from std_msgs.msg import String

        from agv_nodes.demo import comms_handshake, silent_links
        from agv_nodes.graph.parameters import wait_links

        self.spin_until(lambda: self.launch.moving.is_set()
                        and self.task_pub.get_subscription_count() > 0, 120, 'the graph')
        comms_handshake(lambda: self.executor.spin_once(timeout_sec=0.05),
                        lambda words: self.task_pub.publish(String(data=words)), self.reports,
                        alive=lambda: not [n for n in self.launch.poll()
                                           if n not in self.expected_dead])
        # as agv-demo: every link has carried a record before the task goes
        links, quiet = wait_links(self.launch.graph), self.launch.silent_records
        try:
            self.spin_until(lambda: not silent_links(links, self.accepted(), quiet), 60,
                            'every link to carry a record')
        except AssertionError as exc:
            silent = silent_links(links, self.accepted(), self.launch.silent_records)
            raise AssertionError(f'silent: {silent}; {exc}') from None

    def _call(self, client, what: str) -> str:
        from std_srvs.srv import Trigger

        assert client.wait_for_service(timeout_sec=30.0), f'no {what} service'
        future = client.call_async(Trigger.Request())
        deadline = time.monotonic() + 30
        while not future.done():
            self.executor.spin_once(timeout_sec=0.05)
            assert time.monotonic() < deadline, f'{what} did not answer'
        return future.result().message

    def at_exact_time(self, action) -> float:
        """Pause the world, do `action()`, resume; returns the sim time it happened at."""
        at = float(self._call(self._pause, 'world pause').split()[2])  # 'paused at T s'
        action()
        self._call(self._resume, 'world resume')
        return at

    def set_world(self, **values: Any) -> None:
        """Set world parameters at run time (fault switches)."""
        self.set_parameters('world', **values)

    def set_parameters(self, node: str, **values: Any) -> None:
        """Set a node's parameters at run time (fault switches)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        client = self.node.create_client(SetParameters, f'{node}/set_parameters')
        assert client.wait_for_service(timeout_sec=30.0)
        req = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                                for k, v in values.items()])
        future = client.call_async(req)
        while not future.done():
            self.executor.spin_once(timeout_sec=0.05)
        assert all(r.successful for r in future.result().results), future.result()

    def radio_stop(self, on: bool) -> None:
        """Set the radio-control stop input."""
        from std_msgs.msg import Bool

        self.radio_pub.publish(Bool(data=on))

    # -- what happened ----------------------------------------------------------------------
    def stays_at_rest(self, hold: float = 2.0, wall_limit: float = 120, what: str = '') -> float:
        """Wait until the truck is at rest and has stayed so for `hold` sim s; returns since."""
        rest: dict[str, float | None] = {'since': None}

        def held() -> bool:
            if self.speed > AT_REST:
                rest['since'] = None
                return False
            if rest['since'] is None:
                rest['since'] = self.time
            return self.time - rest['since'] >= hold
        self.spin_until(held, wall_limit, what or 'the truck to stop and stay stopped')
        return float(rest['since'])

    def drive_off_after(self, t: float) -> float | None:
        """Sim seconds from `t` to the first drive_off event after it (None: none)."""
        cut = [e_t - t for e_t, e in self.events if e['event'] == 'drive_off' and e_t >= t - 0.05]
        return cut[0] if cut else None

    def drive_off_ms(self, t: float, within: float) -> int:
        """Whole ms from `t` to the drive going off, asserted in (0, `within` s].

        world_event stamps are whole milliseconds, so the budget is compared in them
        (0.2 + 2e-16 s is 200 ms).
        """
        cut = self.drive_off_after(t)
        assert cut is not None, f'no drive_off after {t:.3f} s (events {self.events})'
        ms = round(cut * 1000)
        assert 0 < ms <= round(within * 1000), f'drive off {ms} ms after {t:.3f} s'
        return ms

    def travelled_since(self, t0: float) -> float:
        """Metres along the ground-truth path since sim time `t0`."""
        pts = [(x, y) for t, x, y in self.path if t >= t0]
        return sum(math.dist(a, b) for a, b in zip(pts, pts[1:], strict=False))

    def report_with(self, words: str, wall_limit: float = 30) -> None:
        """Wait for a comms/report containing `words`."""
        self.spin_until(lambda: any(words in r for r in self.reports), wall_limit,
                        f'a report with {words!r}')

    def close(self) -> None:
        """Shut the probe and the graph down."""
        import rclpy

        self.node.destroy_node()
        self.radio_node.destroy_node()
        self.executor.shutdown()
        rclpy.try_shutdown(context=self.context)
        self.launch.stop()
