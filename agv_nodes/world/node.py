"""world: the simulated truck, floor, markers and sensors (ros2 run agv_nodes world).

A thin rclpy wrapper around `agv_nodes.world.core.WorldCore`: it feeds the hardware-side input
records to the core, steps it once per marker-sensor sample, and publishes the hardware-side
records, camera frames, ground truth and (with use_sim_time) /clock. A hardware driver could
replace it topic for topic (docs/records.md, docs/hardware.md).

The world is the clock: it runs its own loop, not a ROS timer (agv_nodes/world/loop.py, a part
the node owns: waiting for the graph, pacing, stepping).

With `trucks` set the world is a floor of several trucks, each a world node of its own in its
truck's namespace, stepped together on one clock (agv_nodes/world/floor.py).

Faults switched at run time: `sensor.ambient`, `wire_powered`, `sonar.enabled` and the
CONCIC-II's `concic2.estop`, `concic2.controller_fault`, `concic2.encoder_fault`,
`concic2.battery_voltage`; the service
`~/hardware_reset` (std_srvs/Trigger) presses the CONCIC-II's reset, which clears the safety
PAL's latches (Rajagopalan 1991, 6.3.11).

The CONCIC-II's front sonar pings on hw/sonar (sensor_msgs/Range, agv_nodes/world/sonar.py);
world/obstacles (std_msgs/String, one JSON command a message) places and removes obstacles on the
floor while it runs (agv_nodes/world/obstacles.py), a refused command logged in one line and
counted in /diagnostics; world/obstacle_markers (visualization_msgs/MarkerArray, latched) draws
the obstacles standing, re-sent whole on every change.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
import math
import sys
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, Range
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from agv_nodes import qos, sim_progress
from agv_nodes.node_process import spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.rclpy_internals import drop_clock_reader
from agv_nodes.records import codec
from agv_nodes.records.carrier import clock_cdr
from agv_nodes.ros_ports import (
    InputDiagnostics,
    RecordPublisher,
    RecordSubscription,
    clock_time_ns,
)
from agv_nodes.settings import SettingError, convert, parameters
from agv_nodes.stop_switches import SwitchSubscription
from agv_nodes.world import kernels
from agv_nodes.world.core import WorldCore
from agv_nodes.world.floor import Control, Floor, Place, set_down
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.layout_check import enforce
from agv_nodes.world.loop import WorldLoop
from agv_nodes.world.obstacles import ObstacleCommands
from agv_nodes.world.pacing import GraphPacer
from agv_nodes.world.peers import LinkWatch, parse_link_entry
from agv_nodes.world.settings import WorldNodeSettings, WorldParams
from agv_nodes.world.viz import camera_image, layout_messages, obstacle_markers, pose_message

NODE = 'world'


def _readers_of(writer: RecordPublisher) -> Callable[[], int]:
    """Return the count of a record writer's matched readers, as LinkWatch polls it."""
    return lambda: writer.subscription_count


class WorldNode(Node):
    """See the module docstring; its loop is its part `loop` (agv_nodes.world.loop)."""

    def __init__(self, namespace: str | None = None, place: Place | None = None) -> None:
        """Make the world of one truck; with `trucks` set and no `place`, the floor of all.

        `namespace` and `place` are given by the floor to each truck's world node.
        """
        super().__init__(NODE, namespace=namespace)
        self.s = s = declare(self, WorldNodeSettings)
        self.node_settings = s  # record_writers: whom its record inputs come from
        wp = declare(self, WorldParams)
        refuse_unknown(self)
        self.executor_kind = s.executor
        self.layout = self._load_layout(s)
        self.control = place.control if place is not None else Control(paused=s.start_paused)
        self.work = 0  # callbacks run: the loop drains until this stops growing
        self.loop = WorldLoop(self)
        self.floor: Floor | None = None
        self.core: WorldCore | None = None
        if s.trucks and place is None:  # the floor: a world node per truck, stepped here
            self.clock_pub = self.create_publisher(Clock, '/clock', qos.STREAM_WRITER)
            self.floor = Floor(self, s, wp, lambda ns, pl: WorldNode(ns, pl))
            self.members = self.floor.members
            self.peers = LinkWatch(self, self._links(s, ()), {}, {
                sim_progress.CLOCK_LINK: self.clock_pub.get_subscription_count})
            self._serve()
            return
        self.members = [self]
        try:  # a marker the sensor cannot read as the truck drives there (agv-layout check)
            for line in enforce(self.layout, wp, s.layout_check):
                self.get_logger().warning(line)
        except LayoutError as exc:
            raise parameter_error(self, 'layout', s.layout, str(exc)) from None
        if place is not None:
            wp = replace(wp, seed=wp.seed + place.index)  # each truck's sensors their own noise
        start = set_down(self, s, place)
        try:  # 'c' where the kernels were not built (no C compiler at install)
            kernels.select(wp.kernels)
        except ValueError as exc:
            raise parameter_error(self, 'kernels', wp.kernels, str(exc)) from None
        self.core = WorldCore(self.layout, wp, start=start,
                              station_loads=place.station_loads if place is not None else None)
        self.core.wire_powered = s.wire_powered
        c = codec()
        self.out = {sch.name: RecordPublisher(self, sch) for sch in c if sch.writer == NODE}
        self.inputs = {sch.name: RecordSubscription(self, sch, callback=self._input(sch.name))
                       for sch in c if NODE in sch.readers}
        # the radio stop from its named writer only (agv_nodes/stop_switches.py)
        self.radio_switch = SwitchSubscription(self, 'radio_stop', self._radio_stop)
        self.input_diagnostics = InputDiagnostics(self, {**self.inputs,
                                                         'radio_stop': self.radio_switch})
        self.pacer = GraphPacer(s.max_lag, s.pace_nodes,
                                clock_step=s.clock_every / wp.sample_rate)
        progress = {node: self.create_subscription(Clock, sim_progress.topic(node),
                                                   self._progress(node), qos.PROGRESS,
                                                   raw=True)
                    for node in s.pace_nodes}
        own_readers = {name: r.publisher_count for name, r in self.inputs.items()}
        own_readers.update({f'{sim_progress.LINK}.{node}': sub.get_publisher_count
                            for node, sub in progress.items()})
        # a truck of a floor: the floor writes /clock, and its root node waits for its readers
        self.clock_pub = place.clock_pub if place is not None else \
            self.create_publisher(Clock, '/clock', qos.STREAM_WRITER)
        own_writers = {name: _readers_of(w) for name, w in self.out.items()}
        if place is None:
            own_writers[sim_progress.CLOCK_LINK] = self.clock_pub.get_subscription_count
        self.peers = LinkWatch(self, self._links(s, s.pace_nodes), own_readers, own_writers)
        self.bumper_pub = self.create_publisher(Bool, 'hw/bumper', qos.LATCHED)
        self._bumper = False
        self.pose_pub = self.create_publisher(PoseStamped, 'world/pose', qos.STREAM_WRITER)
        self.camera_pubs = {name: self.create_publisher(Image, f'hw/camera/{name}',
                                                        qos.STREAM_WRITER)
                            for name in ('front', 'rear')}
        self.sonar_pub = self.create_publisher(Range, 'hw/sonar', qos.STREAM_WRITER) \
            if self.core.sonar is not None else None
        self.obstacle_commands = ObstacleCommands(self.core.obstacles)
        self.input_diagnostics.add('obstacles', self.obstacle_commands)
        self.create_subscription(String, 'world/obstacles', self._obstacle_command, qos.EVENTS)
        route, markers = layout_messages(self.layout)
        self.create_publisher(PathMsg, 'world/route', qos.LATCHED).publish(route)
        self.create_publisher(MarkerArray, 'world/markers', qos.LATCHED).publish(markers)
        self.obstacle_pub = self.create_publisher(MarkerArray, 'world/obstacle_markers',
                                                  qos.LATCHED)
        self.obstacle_pub.publish(obstacle_markers(self.core.obstacles))
        self._pose_every = max(1, round(wp.sample_rate / 50.0))
        self._serve()

    def _serve(self) -> None:
        """Offer the run-time faults and the services, last: a found service means it runs."""
        # The world writes /clock, so it sets its own ROS clock as it does (publish_clock_now)
        # instead of reading every /clock back over DDS: that wakes its loop once more per clock
        # step, and while it waited for its peers the loop spun on its own clock thousands of
        # times a second, flooding every node with it.
        # (Not rclpy's own `_time_source` attribute: that stays as rclpy set it.)
        self._clock_source = drop_clock_reader(self) if self.s.publish_clock and \
            self.get_parameter('use_sim_time').value else None
        # every ROS clock this node's /clock sets: its own and, on a floor, each truck world's
        # (made, with theirs, before the floor's own _serve)
        self._clock_feeds = [n._clock_source for n in dict.fromkeys((self, *self.members))
                             if n._clock_source is not None]
        self._clock_msg = Clock()
        self.add_on_set_parameters_callback(self._set_at_run_time)
        for name in ('pause', 'resume', 'step', 'hardware_reset'):
            self.create_service(Trigger, f'~/{name}', getattr(self, f'_service_{name}'))

    def _links(self, s: WorldNodeSettings, paced: tuple[str, ...]
               ) -> list[tuple[str, str, int | None]]:
        links = []
        for entry in s.wait_for_links:
            link = parse_link_entry(entry)
            if link is None:
                raise parameter_error(self, 'wait_for_links', entry,
                                      'not NODE:RECORD or NODE>RECORD:N')
            links.append(link)
        return links + [(NODE, f'{sim_progress.LINK}.{node}', None) for node in paced]

    @property
    def time(self) -> float:
        """The floor's simulated seconds (every truck's world keeps the same time)."""
        return self.members[0].core.time

    def _load_layout(self, s: WorldNodeSettings) -> Any:
        try:
            layout = load_layout(layout_path(s.layout))
        except (LayoutError, FileNotFoundError) as exc:
            raise parameter_error(self, 'layout', s.layout, str(exc)) from None
        names = {m.name for m in layout.markers}
        for name in s.remove_markers:
            if name not in names:
                raise parameter_error(self, 'remove_markers', list(s.remove_markers),
                                      f'no marker {name!r} in layout {layout.name} '
                                      f'({", ".join(sorted(names))})')
        layout.markers = [m for m in layout.markers if m.name not in s.remove_markers]
        return layout

    @property
    def truck(self) -> WorldCore:
        """Return this truck's world (a floor's own node has none: its trucks' nodes have)."""
        if self.core is None:
            raise RuntimeError(f'{self.get_name()}: a floor node has no truck of its own')
        return self.core

    # -- callbacks --------------------------------------------------------------------------
    def _input(self, name: str):
        def on_record(fields: dict) -> None:
            self.work += 1
            self.truck.on_record(name, fields, self.truck.time)
        return on_record

    def _progress(self, node: str):
        def on_progress(raw: bytes) -> None:
            self.work += 1
            self.pacer.progress(node, clock_time_ns(raw) * 1e-9, self.truck.time)
        return on_progress

    def _set_at_run_time(self, params: list) -> SetParametersResult:
        """Faults switched while the world runs: light, the wire generator, the CONCIC-II's.

        Set on a floor's own node, a fault reaches every truck; on a truck's, that truck.
        """
        concic2 = {p.name: p for p in parameters(WorldParams)
                   if p.name.startswith('concic2.') and not p.spec.read_only}
        for param in params:
            if param.name in concic2:  # choices and ranges checked before any is applied
                try:
                    convert(concic2[param.name], param.value)
                except SettingError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        for core in (m.core for m in self.members):
            for param in params:
                if param.name == 'sensor.ambient':
                    core.sensor.p.ambient = float(param.value)
                elif param.name == 'wire_powered':
                    core.wire_powered = bool(param.value)
                elif param.name == 'sonar.enabled':  # silenced: hw/sonar stops
                    core.p.sonar.enabled = bool(param.value)
                elif param.name == 'clock_offset':  # /clock jumps by the change
                    self.s.clock_offset = float(param.value)
                elif param.name in concic2:
                    setattr(core.p.concic2, param.name.split('.', 1)[1],
                            convert(concic2[param.name], param.value))
        return SetParametersResult(successful=True)

    def _obstacle_command(self, msg: String) -> None:
        self.work += 1
        applied, line = self.obstacle_commands.take(msg.data, round(self.time * 1e9))
        if applied:
            self.obstacle_pub.publish(obstacle_markers(self.truck.obstacles))
        log = self.get_logger()
        (log.info if applied else log.warning)(f'{line} at {self.time:.3f} s')

    def _radio_stop(self, on: bool) -> None:
        self.work += 1
        self.truck.set_radio_stop(on)

    def _service_pause(self, _req: Any, res: Any) -> Any:
        self.work += 1
        self.control.paused = True
        res.success, res.message = True, f'paused at {self.time:.3f} s'
        return res

    def _service_resume(self, _req: Any, res: Any) -> Any:
        self.work += 1
        self.control.paused = False
        res.success, res.message = True, f'resumed at {self.time:.3f} s'
        return res

    def _service_hardware_reset(self, _req: Any, res: Any) -> Any:
        self.work += 1
        for m in self.members:  # a floor's own node: every truck's reset
            m.core.hardware_reset()
        res.success = all(m.core.pal is not None for m in self.members)
        res.message = (f'hardware reset at {self.time:.3f} s' if res.success
                       else 'no safety PAL on this vehicle (the CONCIC-II has one)')
        return res

    def _service_step(self, _req: Any, res: Any) -> Any:
        self.work += 1
        self.control.step_requests += 1
        res.success = self.control.paused
        res.message = 'one sample queued' if self.control.paused else 'not paused: ~/pause first'
        return res

    # -- output -----------------------------------------------------------------------------
    def stamp(self) -> Time:
        """Sim time when publishing /clock, else the node clock."""
        if self.s.publish_clock:
            sec, nanosec = divmod(round(self.time * 1e9), 1_000_000_000)
            return Time(sec=sec, nanosec=nanosec)
        return self.get_clock().now().to_msg()

    def publish_clock_now(self) -> None:
        """Publish /clock at the world's time, serialized here.

        It is the world's busiest publisher (116 Hz to every node): a Python Clock message per
        sample cost more than the bytes.
        """
        now = round(self.time * 1e9)
        self.clock_pub.publish(clock_cdr(now + round(self.s.clock_offset * 1e9)))
        if self._clock_feeds:
            msg = self._clock_msg
            msg.clock.sec, msg.clock.nanosec = divmod(now, 1_000_000_000)
            for source in self._clock_feeds:
                source.clock_callback(msg)

    def publish_events(self, events: list[dict[str, Any]]) -> None:
        """Publish world events as world_event records; the bumper switch when it changed."""
        for event in events:
            self.out['world_event'].publish({**{k: event[k] for k in (
                'event', 'marker_kind', 'identity', 'error', 'speed', 'lateral', 'count',
                'station')}, 'time_ms': round(event['time'] * 1000) & 0xFFFF})
        if self.truck.bumper != self._bumper:  # the bumper switch, to traction
            self._bumper = self.truck.bumper
            self.bumper_pub.publish(Bool(data=self._bumper))

    def _range(self, reading: float) -> Range:
        """hw/sonar: one ping as REP 117 has it (+inf: no echo, -inf: nearer than min_range)."""
        p = self.truck.p.sonar
        msg = Range(radiation_type=Range.ULTRASOUND, field_of_view=math.radians(p.beam),
                    min_range=p.min_range, max_range=p.max_range, range=reading)
        msg.header.stamp, msg.header.frame_id = self.stamp(), 'sonar_front'
        return msg

    def publish_step(self, out: dict) -> None:
        """Publish what one core step produced (not /clock: the floor's loop does)."""
        for name, fields in out['records'].items():
            self.out[name].publish(fields)
        self.publish_events(out['events'])
        pose_due = self.truck.sample % self._pose_every == 0
        stamp = self.stamp() if out['frames'] or pose_due else None
        for name, frame in out['frames'].items():
            self.camera_pubs[name].publish(camera_image(frame, name, stamp))
        if out.get('sonar') is not None and self.sonar_pub is not None:
            self.sonar_pub.publish(self._range(out['sonar']))
        if pose_due:
            x, y, h, _v = self.truck.pose()
            self.pose_pub.publish(pose_message(x, y, h, stamp))


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes world [--ros-args ...]."""
    return spin_main(WorldNode, args, run=lambda node, executor: node.loop.run(executor))


if __name__ == '__main__':
    sys.exit(main())
