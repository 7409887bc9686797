"""world: the simulated truck, floor, markers and sensors (ros2 run agv_nodes world).

A thin rclpy wrapper around `agv_nodes.world.core.WorldCore`: it feeds the hardware-side input
records to the core, steps it once per marker-sensor sample, and publishes the hardware-side
records, camera frames, ground truth and (with use_sim_time) /clock. A hardware driver could
replace it topic for topic (docs/records.md, DESIGN.md "Topics").

The world is the clock: it does not run on a ROS timer (a sim-time timer cannot fire faster than
/clock advances, and the world is what advances it). Its own loop steps the core, publishes
/clock every sample, services its subscriptions and services, and paces itself at `time_factor`
x real time (0 = as fast as the machine allows). It waits until the topics named in
`wait_for_subscribers` have readers (and `wait_for_publishers` have writers), and every node
has said on graph/links that its readers of the `wait_for_links` records have matched their
writers, before moving.
"""

from __future__ import annotations

from collections.abc import Callable
import math
import sys
import time
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image
from std_msgs.msg import Bool, String, UInt8MultiArray
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from agv_nodes import qos
from agv_nodes.core_node import declare_executor, running, spin_main
from agv_nodes.params import Parameters
from agv_nodes.records import codec
from agv_nodes.records.carrier import clock_cdr
from agv_nodes.records.codec import RecordError, RecordSchema
from agv_nodes.ros_ports import (
    LINKS_TOPIC,
    InputDiagnostics,
    RecordPublisher,
    RecordSubscription,
    parse_links,
    record_bytes,
)
from agv_nodes.world.core import WorldCore, WorldParams
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.pacing import GraphPacer
from agv_nodes.world.vehicles import Concic2Params, ElectrukParams

NODE = 'world'
INPUTS = ('traction_drive', 'steering_command', 'conveyor_command')


def parse_link_entry(entry: str) -> tuple[str, str, int | None] | None:
    """A `wait_for_links` entry: 'NODE:RECORD' -> (node, record, None); 'NODE>RECORD:N' ->
    (node, record, N); None when it is neither (or names no record)."""
    if '>' in entry:
        node, _, rest = entry.partition('>')
        record, _, count = rest.partition(':')
        readers = int(count) if count.isdigit() and int(count) > 0 else None
        if not node or record not in codec() or readers is None:
            return None
        return node, record, readers
    node, _, record = entry.partition(':')
    return (node, record, None) if node and record in codec() else None


# Fields by which a record reports how many samples of a world stream its writer has taken
# (pacing.py): the position sensor's ADC snapshots, route following's guide_wire records.
COUNT_FIELDS = ('sample_count', 'wire_count')


def _count_field(schema: RecordSchema) -> str | None:
    """The field of `schema` that counts world samples taken (COUNT_FIELDS), if any."""
    return next((f.name for f in schema.fields if f.name in COUNT_FIELDS), None)


class WorldNode(Node):
    """See the module docstring."""

    def __init__(self) -> None:
        super().__init__(NODE)
        p = Parameters(self)
        layout_name = p.text('layout', 'demo_1983', 'layout name (config/layouts) or file path')
        try:
            self.layout = load_layout(layout_path(layout_name))
        except (LayoutError, FileNotFoundError) as exc:
            p.fail('layout', layout_name, str(exc))
        removed = p.texts('remove_markers', [], 'marker cards taken off their stands (fault '
                          'tests: a missing stop marker), by name: L0-L3, W2.1, ...')
        names = {m.name for m in self.layout.markers}
        for name in removed:
            if name not in names:
                p.fail('remove_markers', removed, f'no marker {name!r} in layout '
                       f'{self.layout.name} ({", ".join(sorted(names))})')
        self.layout.markers = [m for m in self.layout.markers if m.name not in removed]
        wp = WorldParams(
            seed=p.integer('seed', 1, 'random seed of all noise', 0, 2**31 - 1),
            sample_rate=p.number('sample_rate', 340.0, 'marker sensor snapshots per second '
                                 '(thesis 5.3.5.2: 340 Hz)', 50.0, 2000.0),
            camera_rate=p.number('camera_rate', 20.0, 'binary camera frames per second', 1.0,
                                 50.0),
            rear_camera=p.flag('rear_camera', False, 'render the rear camera too'),
        )
        wp.electruk = ElectrukParams(
            payload=p.number('payload', 0.0, 'payload on the Electruk, kg (thesis: <= 1000)',
                             0.0, 2000.0))
        wp.concic2 = Concic2Params()
        wp.sensor.unit = p.choice('sensor_unit', 'sensor1', 'Table 7.1 sensor whose gains the '
                                  'photodiode model reproduces', ('sensor1', 'sensor2'))
        wp.sensor.ambient = p.number('ambient', 0.0, 'ambient IR light, ADC counts (255 '
                                     'saturates: a blinded sensor)', 0.0, 400.0)
        wp.sensor.noise = p.number('adc_noise', 1.0, 'ADC noise, counts rms', 0.0, 20.0)
        loaded = p.texts('start_loaded', [], 'truck conveyors carrying a load at start '
                         '(first, second)')
        for name in loaded:
            if name not in ('first', 'second'):
                p.fail('start_loaded', loaded, f'{name!r} is not first or second')
        wp.start_loaded = ('first' in loaded, 'second' in loaded)
        self.time_factor = p.number('time_factor', 1.0, 'simulated seconds per real second '
                                    '(0 = as fast as possible)', 0.0, 1000.0)
        self.executor_kind = declare_executor(p)
        self.publish_clock = p.flag('publish_clock', True, 'publish /clock (the graph runs on '
                                    'sim time with use_sim_time:=true)')
        self.clock_every = p.integer('clock_every', 1, 'samples per /clock message (1 = every '
                                     '340 Hz sample; keep the clock faster than the fastest node '
                                     'timer)', 1, 100)
        self.wait_subs = p.texts('wait_for_subscribers', [], 'topics that need a reader '
                                 'before the world moves')
        self.wait_pubs = p.texts('wait_for_publishers', [], 'topics that need a writer '
                                 'before the world moves')
        links = p.texts('wait_for_links', [], "links that must have matched before the world "
                        "moves: NODE:RECORD (NODE's reader has matched the record's writer) or "
                        "NODE>RECORD:N (NODE's writer has matched N readers); graph/links, "
                        'agv-launch names every link of the graph')
        self.wait_links: list[tuple[str, str, int | None]] = []
        for entry in links:
            link = parse_link_entry(entry)
            if link is None:
                p.fail('wait_for_links', links, f'{entry!r} is not NODE:RECORD or '
                       'NODE>RECORD:N')
            self.wait_links.append(link)
        self.peer_timeout = p.number('peer_timeout', 60.0, 'seconds to wait for peers', 0.0,
                                     3600.0)
        self.duration = p.number('duration', 0.0, 'stop after this many simulated seconds '
                                 '(0 = run until shut down)', 0.0, 1e6)
        self.paused = p.flag('start_paused', False, 'wait for ~/resume before moving')
        c = codec()
        pace_on = p.texts('pace_on', ['traction_drive', 'steering_command'], 'records whose '
                          'writers the world waits for when they lag (world/pacing.py; '
                          'agv-launch names every node of the graph)')
        for name in pace_on:
            if name not in c or c[name].writer == NODE:
                p.fail('pace_on', pace_on, f'{name!r} is not a record another node writes')
        max_lag = p.number('max_lag', 0.05, 'simulated seconds a paced record may lag the '
                           'world beyond its period before the world waits (0 = never wait)',
                           0.0, 10.0)
        self.lag_patience = p.number('lag_patience', 0.5, 'real seconds the world waits for a '
                                     'lagging writer before it carries on without it', 0.0, 60.0)
        slack = {}
        entries = p.texts('pace_slack', [], 'RECORD:SECONDS: extra time a paced record may '
                          'lag (agv-launch --fault sets it for a lossy or delayed record)')
        for entry in entries:
            name, _, seconds = entry.partition(':')
            try:
                slack[name] = float(seconds)
            except ValueError:
                p.fail('pace_slack', entries, f'{entry!r} is not RECORD:SECONDS')
        self.pacer = GraphPacer(
            max_lag, {name: c[name].period_ms / 1000.0 for name in pace_on}, wp.sample_rate,
            clock_step=self.clock_every / wp.sample_rate,
            consumers=tuple(n for n in pace_on if _count_field(c[n])), slack=slack,
            consumer_rates={n: wp.guide_wire_rate for n in pace_on
                            if _count_field(c[n]) == 'wire_count'})
        self.core = WorldCore(self.layout, wp)
        # each count field's stream: how many samples of it the world has published
        self._published: dict[str, Callable[[], int]] = {
            'sample_count': lambda: self.core.sample,
            'wire_count': lambda: self.core.wire_records}
        self.core.wire_powered = p.flag('wire_powered', True, 'guide-wire generator on (set '
                                        'false at run time to cut the wire: a fault test)')
        self.add_on_set_parameters_callback(self._set_at_run_time)
        self.out = {}
        for schema in c:
            if schema.writer == NODE:
                self.out[schema.name] = RecordPublisher(self, schema)
        self.inputs = {name: RecordSubscription(self, c[name], callback=self._input(name))
                       for name in INPUTS}
        self.input_diagnostics = InputDiagnostics(self, self.inputs)
        # matched-writer counts of the world's own readers (its `wait_for_links` entries)
        self._own_links = {name: reader.publisher_count for name, reader in self.inputs.items()}
        for name in pace_on:  # only the arrival (and a sample count) matter: read raw
            if name not in INPUTS:
                sub = self.create_subscription(UInt8MultiArray, c[name].topic,
                                               self._paced(c[name]), qos.reader_qos(c[name]),
                                               raw=True)
                self._own_links[name] = sub.get_publisher_count
        self.create_subscription(Bool, 'hw/radio_stop', self._radio_stop, qos.RECORD_READER)
        self._links: dict[str, set[str]] = {}  # node -> its inputs matched (graph/links)
        self._link_outputs: dict[str, dict[str, int]] = {}  # node -> readers its outputs matched
        self.create_subscription(String, LINKS_TOPIC, self._on_links, qos.LINKS_READER)
        self.clock_pub = self.create_publisher(Clock, '/clock', qos.STREAM_WRITER)
        self.pose_pub = self.create_publisher(PoseStamped, 'world/pose', qos.STREAM_WRITER)
        self.route_pub = self.create_publisher(Path, 'world/route', qos.LATCHED)
        self.markers_pub = self.create_publisher(MarkerArray, 'world/markers', qos.LATCHED)
        self.camera_pubs = {name: self.create_publisher(Image, f'hw/camera/{name}',
                                                        qos.STREAM_WRITER)
                            for name in ('front', 'rear')}
        self.create_service(Trigger, '~/pause', self._pause)
        self.create_service(Trigger, '~/resume', self._resume)
        self.create_service(Trigger, '~/step', self._single_step)
        self._step_requests = 0
        self._work = 0
        self._pose_every = max(1, round(wp.sample_rate / 50.0))
        self._publish_static()

    # -- callbacks --------------------------------------------------------------------------
    def _input(self, name: str):
        field = _count_field(codec()[name])
        published = self._published.get(field)

        def on_record(fields: dict) -> None:
            self._work += 1
            if published is None:
                self.pacer.arrived(name, self.core.time)
            else:
                self.pacer.arrived(name, self.core.time, fields[field], published())
            self.core.on_record(name, fields)
        return on_record

    def _paced(self, schema: RecordSchema):
        field = _count_field(schema)
        published = self._published.get(field, lambda: 0)

        def on_msg(raw: bytes) -> None:
            self._work += 1
            count = None
            if field:  # pacing only: a record that does not decode just counts as heard
                data = record_bytes(raw)
                for integrity in ('e2e', 'none'):
                    try:
                        count = schema.decode(data, integrity=integrity)[field]
                        break
                    except RecordError:
                        continue
            self.pacer.arrived(schema.name, self.core.time, count, published())
        return on_msg

    def _on_links(self, msg: String) -> None:
        node, inputs, outputs = parse_links(msg.data)
        self._links[node] = inputs
        self._link_outputs[node] = outputs

    def _set_at_run_time(self, params: list) -> SetParametersResult:
        """Faults switched while the world runs: ambient light and the wire generator."""
        for param in params:
            if param.name == 'ambient':
                self.core.sensor.p.ambient = float(param.value)
            elif param.name == 'wire_powered':
                self.core.wire_powered = bool(param.value)
        return SetParametersResult(successful=True)

    def _radio_stop(self, msg: Bool) -> None:
        self._work += 1
        self.core.set_radio_stop(msg.data)

    def _pause(self, _req, res):
        self._work += 1
        self.paused = True
        res.success, res.message = True, f'paused at {self.core.time:.3f} s'
        return res

    def _resume(self, _req, res):
        self._work += 1
        self.paused = False
        res.success, res.message = True, f'resumed at {self.core.time:.3f} s'
        return res

    def _single_step(self, _req, res):
        self._work += 1
        self._step_requests += 1
        res.success = self.paused
        res.message = ('one sample queued' if self.paused else 'not paused: ~/pause first')
        return res

    # -- output -----------------------------------------------------------------------------
    def stamp(self) -> Time:
        """Sim time when publishing /clock, else the node clock."""
        if self.publish_clock:
            ns = round(self.core.time * 1e9)
            return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return self.get_clock().now().to_msg()

    def publish_clock_now(self) -> None:
        """/clock at the world's time, serialized here (the world's busiest publisher: 116 Hz
        to every node; a Python Clock message per sample cost more than the bytes)."""
        self.clock_pub.publish(clock_cdr(round(self.core.time * 1e9)))

    def publish_step(self, out: dict) -> None:
        """Publish what one core step produced."""
        if self.publish_clock and self.core.sample % self.clock_every == 0:
            self.publish_clock_now()
        for name, fields in out['records'].items():
            self.out[name].publish(fields)
        for event in out['events']:
            self.out['world_event'].publish({**{k: event[k] for k in (
                'event', 'marker_kind', 'identity', 'error', 'speed', 'lateral', 'count',
                'station')}, 'time_ms': round(event['time'] * 1000) & 0xFFFF})
        stamp = self.stamp() if out['frames'] or self.core.sample % self._pose_every == 0 \
            else None
        for name, frame in out['frames'].items():
            img = Image()
            img.header.stamp = stamp
            img.header.frame_id = f'camera_{name}'
            img.height, img.width = frame.shape
            img.encoding = 'mono8'
            img.step = img.width
            img.data = ((1 - frame) * 255).astype('uint8').tobytes()  # tape dark = 0
            self.camera_pubs[name].publish(img)
        if self.core.sample % self._pose_every == 0:
            x, y, h, _v = self.core.pose()
            msg = PoseStamped()
            msg.header.stamp = stamp
            msg.header.frame_id = 'map'
            msg.pose.position.x, msg.pose.position.y = x, y
            msg.pose.orientation.z, msg.pose.orientation.w = math.sin(h / 2), math.cos(h / 2)
            self.pose_pub.publish(msg)

    def _publish_static(self) -> None:
        path = Path()
        path.header.frame_id = 'map'
        markers = MarkerArray()
        for k, p in enumerate(self.layout.paths.values()):
            strip = Marker(ns='paths', id=k, type=Marker.LINE_STRIP, action=Marker.ADD)
            strip.header.frame_id = 'map'
            strip.scale.x = max(p.width, 0.01)
            strip.color.a, strip.color.r, strip.color.g, strip.color.b = 1.0, 0.9, 0.6, 0.1
            strip.pose.orientation.w = 1.0
            for (x, y), h in zip(p.points[::5], p.headings[::5], strict=True):
                pose = PoseStamped()
                pose.header.frame_id = 'map'
                pose.pose.position.x, pose.pose.position.y = float(x), float(y)
                pose.pose.orientation.z = math.sin(h / 2)
                pose.pose.orientation.w = math.cos(h / 2)
                path.poses.append(pose)
                strip.points.append(Point(x=float(x), y=float(y)))
            markers.markers.append(strip)
        for k, m in enumerate(self.layout.markers):
            card = Marker(ns='cards', id=k, type=Marker.CUBE, action=Marker.ADD)
            card.header.frame_id = 'map'
            card.pose.position.x, card.pose.position.y = float(m.centre[0]), float(m.centre[1])
            card.pose.position.z = 0.5
            yaw = math.atan2(m.along[1], m.along[0])
            card.pose.orientation.z, card.pose.orientation.w = math.sin(yaw / 2), \
                math.cos(yaw / 2)
            card.scale.x, card.scale.y, card.scale.z = m.columns * 0.02, 0.01, 0.08
            card.color.a = 1.0
            card.color.r = 1.0 if m.kind == 'stop' else 0.2
            card.color.g = 1.0 if m.kind == 'location' else 0.2
            markers.markers.append(card)
            label = Marker(ns='labels', id=k, type=Marker.TEXT_VIEW_FACING, action=Marker.ADD,
                           text=m.name)
            label.header.frame_id = 'map'
            label.pose = card.pose
            label.pose.position.z = 0.8
            label.scale.z = 0.2
            label.color.a = label.color.r = label.color.g = label.color.b = 1.0
            markers.markers.append(label)
        self.route_pub.publish(path)
        self.markers_pub.publish(markers)

    # -- the loop ---------------------------------------------------------------------------
    def drain(self, executor: Any, limit: int = 200) -> None:
        """Run every callback that is ready now (inputs, services)."""
        for _ in range(limit):
            before = self._work
            executor.spin_once(timeout_sec=0.0)
            if self._work == before:
                return

    def peers_ready(self) -> bool:
        """True when every awaited topic has its reader/writer."""
        ns = self.get_namespace().rstrip('/')

        def needed(entry: str) -> tuple[str, int]:  # 'topic' or 'topic:N' (at least N peers)
            topic, _, count = entry.partition(':')
            full = topic if topic.startswith('/') else f'{ns}/{topic}'
            return full, int(count) if count.isdigit() else 1

        subs_ok = all(self.count_subscribers(t) >= n for t, n in map(needed, self.wait_subs))
        pubs_ok = all(self.count_publishers(t) >= n for t, n in map(needed, self.wait_pubs))
        return subs_ok and pubs_ok and not self.links_missing()

    def links_missing(self) -> list[str]:
        """`wait_for_links` entries not matched yet (the world's own by its own readers and
        writers, the others as their nodes say on graph/links)."""
        missing = []
        for node, record, readers in self.wait_links:
            if readers is not None:  # the writer's end
                if node == self.get_name():
                    writer = self.out.get(record)
                    count = writer.subscription_count if writer is not None else 0
                else:
                    count = self._link_outputs.get(node, {}).get(record, 0)
                if count < readers:
                    missing.append(f'{node}>{record}:{readers} (has {count})')
                continue
            if node == self.get_name():
                count_of = self._own_links.get(record)
                matched = count_of is not None and count_of() > 0
            else:
                matched = record in self._links.get(node, ())
            if not matched:
                missing.append(f'{node}:{record}')
        return missing

    def _report_pacing(self) -> None:
        """Log how far behind the world's streams each counting reader was heard at worst
        over the last minute (then start over), and the samples accepted as lost."""
        worst = ', '.join(f'{name} {s * 1000:.0f} ms' for name, s in
                          sorted(self.pacer.worst.items()))
        self.get_logger().info(f'pacing, the last minute: worst behind {worst or "-"}; '
                               f'{self.pacer.lost_samples} samples accepted as lost in all')
        self.pacer.worst.clear()

    def run(self, executor: Any) -> int:
        """Wait for peers, then step the world until shut down (or `duration`)."""
        started = time.monotonic()
        deadline = started + self.peer_timeout
        while running() and not self.peers_ready():
            if self.publish_clock:
                self.publish_clock_now()
            executor.spin_once(timeout_sec=0.05)
            if time.monotonic() > deadline:
                self.get_logger().error(
                    f'peers not matched after {self.peer_timeout:.0f} s (subscribers: '
                    f'{self.wait_subs}, publishers: {self.wait_pubs}, links still missing: '
                    f'{self.links_missing()})')
                return 1
        self.get_logger().info(f'layout {self.layout.name}: moving at time_factor '
                               f'{self.time_factor:g} ({len(self.wait_links)} links matched at '
                               f'both ends after {time.monotonic() - started:.2f} s)')
        wall0, sim0 = time.monotonic(), self.core.time
        self.pacer.start(self.core.time)
        report_at = self.core.time + 60.0
        while running():
            if self.core.time >= report_at:
                report_at += 60.0
                self._report_pacing()
            self.drain(executor)
            if self.paused and self._step_requests == 0:
                executor.spin_once(timeout_sec=0.02)
                wall0, sim0 = time.monotonic(), self.core.time
                continue
            if self._step_requests:
                self._step_requests -= 1
            late = self.pacer.lagging(self.core.time)
            if late:  # the graph has fallen behind: let it catch up before time moves on
                waited = time.monotonic()
                nudge = waited + 0.05
                while late and running() and time.monotonic() - waited < self.lag_patience:
                    executor.spin_once(timeout_sec=0.002)
                    late = self.pacer.lagging(self.core.time)
                    if late and self.publish_clock and time.monotonic() > nudge:
                        # The same time again: a node that missed the last /clock (or took
                        # it before its timer could see it) gets another look; timers that
                        # already ran at this time do not run twice.
                        self.publish_clock_now()
                        nudge = time.monotonic() + 0.05
                if late and running():  # (not when a stop request ended the wait)
                    lost = self.pacer.give_up(late)
                    self.get_logger().warn(
                        f'carrying on without {", ".join(late)} (behind for '
                        f'{self.lag_patience:g} s' + (f'; {lost} samples accepted as lost, '
                                                      f'{self.pacer.lost_samples} in all)'
                                                      if lost else ')'))
                wall0, sim0 = time.monotonic(), self.core.time
            self.publish_step(self.core.step())
            if self.duration and self.core.time >= self.duration:
                self.get_logger().info(f'duration {self.duration:g} s reached')
                return 0
            if self.time_factor > 0:
                ahead = (self.core.time - sim0) / self.time_factor - (time.monotonic() - wall0)
                if ahead > 0:
                    time.sleep(ahead)
        return 0


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes world [--ros-args ...]."""
    return spin_main(WorldNode, args, run=lambda node, executor: node.run(executor))


if __name__ == '__main__':
    sys.exit(main())
