"""world: the simulated truck, floor, markers and sensors (ros2 run agv_nodes world).

A thin rclpy wrapper around `agv_nodes.world.core.WorldCore`: it feeds the hardware-side input
records to the core, steps it once per marker-sensor sample, and publishes the hardware-side
records, camera frames, ground truth and (with use_sim_time) /clock. A hardware driver could
replace it topic for topic (docs/records.md, docs/hardware.md).

The world is the clock: it does not run on a ROS timer (a sim-time timer cannot fire faster than
/clock advances, and the world is what advances it). Its own loop steps the core, publishes
/clock, services its subscriptions and services, and paces itself at `time_factor` x real time
(0 = as fast as the graph keeps up: it waits for any node whose sim/progress lags,
agv_nodes/world/pacing.py). It moves once every link named in `wait_for_links` has matched at
both ends (agv_nodes/world/peers.py), then writes `ready_file` (when one is named).

Faults switched at run time: `sensor.ambient`, `wire_powered` and the CONCIC-II's `concic2.estop`,
`concic2.controller_fault`, `concic2.encoder_fault`, `concic2.battery_voltage`; the service
`~/hardware_reset` (std_srvs/Trigger) presses the CONCIC-II's reset, which clears the safety
PAL's latches (Rajagopalan 1991, 6.3.11).
"""

from __future__ import annotations

from pathlib import Path
import sys
import time
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image
from std_msgs.msg import Bool
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from agv_nodes import qos, sim_progress
from agv_nodes.node_process import running, spin_main
from agv_nodes.params import declare, parameter_error, refuse_unknown
from agv_nodes.records import codec
from agv_nodes.records.carrier import clock_cdr
from agv_nodes.ros_ports import (
    InputDiagnostics,
    RecordPublisher,
    RecordSubscription,
    clock_time_ns,
)
from agv_nodes.settings import SettingError, convert, parameters
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import LayoutError, layout_path, load_layout
from agv_nodes.world.layout_check import enforce
from agv_nodes.world.pacing import GraphPacer
from agv_nodes.world.peers import LinkWatch, parse_link_entry
from agv_nodes.world.settings import WorldNodeSettings, WorldParams
from agv_nodes.world.viz import camera_image, layout_messages, pose_message

NODE = 'world'


class WorldNode(Node):
    """See the module docstring."""

    def __init__(self) -> None:
        super().__init__(NODE)
        self.s = s = declare(self, WorldNodeSettings)
        self.node_settings = s  # record_writers: whom its record inputs come from
        wp = declare(self, WorldParams)
        refuse_unknown(self)
        self.executor_kind = s.executor
        self.layout = self._load_layout(s)
        try:  # a marker the sensor cannot read as the truck drives there (agv-layout check)
            for line in enforce(self.layout, wp, s.layout_check):
                self.get_logger().warning(line)
        except LayoutError as exc:
            raise parameter_error(self, 'layout', s.layout, str(exc)) from None
        self.core = WorldCore(self.layout, wp)
        self.core.wire_powered = s.wire_powered
        self.paused = s.start_paused
        c = codec()
        self.out = {sch.name: RecordPublisher(self, sch) for sch in c if sch.writer == NODE}
        self.inputs = {sch.name: RecordSubscription(self, sch, callback=self._input(sch.name))
                       for sch in c if NODE in sch.readers}
        self.input_diagnostics = InputDiagnostics(self, self.inputs)
        self.pacer = GraphPacer(s.max_lag, s.pace_nodes,
                                clock_step=s.clock_every / wp.sample_rate)
        progress = {node: self.create_subscription(Clock, sim_progress.topic(node),
                                                   self._progress(node), qos.PROGRESS,
                                                   raw=True)
                    for node in s.pace_nodes}
        links = []
        for entry in s.wait_for_links:
            link = parse_link_entry(entry)
            if link is None:
                raise parameter_error(self, 'wait_for_links', entry,
                                      'not NODE:RECORD or NODE>RECORD:N')
            links.append(link)
        links += [(NODE, f'{sim_progress.LINK}.{node}', None) for node in s.pace_nodes]
        own_readers = {name: r.publisher_count for name, r in self.inputs.items()}
        own_readers.update({f'{sim_progress.LINK}.{node}': sub.get_publisher_count
                            for node, sub in progress.items()})
        self.clock_pub = self.create_publisher(Clock, '/clock', qos.STREAM_WRITER)
        own_writers = {name: (lambda w=w: w.subscription_count) for name, w in self.out.items()}
        own_writers[sim_progress.CLOCK_LINK] = self.clock_pub.get_subscription_count
        self.peers = LinkWatch(self, links, own_readers, own_writers)
        self.create_subscription(Bool, 'hw/radio_stop', self._radio_stop, qos.RECORD_READER)
        self.bumper_pub = self.create_publisher(Bool, 'hw/bumper', qos.LATCHED)
        self._bumper = False
        self.pose_pub = self.create_publisher(PoseStamped, 'world/pose', qos.STREAM_WRITER)
        self.camera_pubs = {name: self.create_publisher(Image, f'hw/camera/{name}',
                                                        qos.STREAM_WRITER)
                            for name in ('front', 'rear')}
        route, markers = layout_messages(self.layout)
        self.create_publisher(PathMsg, 'world/route', qos.LATCHED).publish(route)
        self.create_publisher(MarkerArray, 'world/markers', qos.LATCHED).publish(markers)
        self.add_on_set_parameters_callback(self._set_at_run_time)
        for name in ('pause', 'resume', 'step', 'hardware_reset'):
            self.create_service(Trigger, f'~/{name}', getattr(self, f'_service_{name}'))
        self._step_requests = 0
        self._work = 0
        self._pose_every = max(1, round(wp.sample_rate / 50.0))

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

    # -- callbacks --------------------------------------------------------------------------
    def _input(self, name: str):
        def on_record(fields: dict) -> None:
            self._work += 1
            self.core.on_record(name, fields, self.core.time)
        return on_record

    def _progress(self, node: str):
        def on_progress(raw: bytes) -> None:
            self._work += 1
            self.pacer.progress(node, clock_time_ns(raw) * 1e-9, self.core.time)
        return on_progress

    def _set_at_run_time(self, params: list) -> SetParametersResult:
        """Faults switched while the world runs: light, the wire generator, the CONCIC-II's."""
        concic2 = {p.name: p for p in parameters(WorldParams)
                   if p.name.startswith('concic2.') and not p.spec.read_only}
        for param in params:
            if param.name in concic2:  # choices and ranges checked before any is applied
                try:
                    convert(concic2[param.name], param.value)
                except SettingError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
        for param in params:
            if param.name == 'sensor.ambient':
                self.core.sensor.p.ambient = float(param.value)
            elif param.name == 'wire_powered':
                self.core.wire_powered = bool(param.value)
            elif param.name in concic2:
                setattr(self.core.p.concic2, param.name.split('.', 1)[1],
                        convert(concic2[param.name], param.value))
        return SetParametersResult(successful=True)

    def _radio_stop(self, msg: Bool) -> None:
        self._work += 1
        self.core.set_radio_stop(msg.data)

    def _service_pause(self, _req: Any, res: Any) -> Any:
        self._work += 1
        self.paused = True
        res.success, res.message = True, f'paused at {self.core.time:.3f} s'
        return res

    def _service_resume(self, _req: Any, res: Any) -> Any:
        self._work += 1
        self.paused = False
        res.success, res.message = True, f'resumed at {self.core.time:.3f} s'
        return res

    def _service_hardware_reset(self, _req: Any, res: Any) -> Any:
        self._work += 1
        self.core.hardware_reset()
        res.success = self.core.pal is not None
        res.message = (f'hardware reset at {self.core.time:.3f} s' if res.success
                       else 'no safety PAL on this vehicle (the CONCIC-II has one)')
        return res

    def _service_step(self, _req: Any, res: Any) -> Any:
        self._work += 1
        self._step_requests += 1
        res.success = self.paused
        res.message = 'one sample queued' if self.paused else 'not paused: ~/pause first'
        return res

    # -- output -----------------------------------------------------------------------------
    def stamp(self) -> Time:
        """Sim time when publishing /clock, else the node clock."""
        if self.s.publish_clock:
            sec, nanosec = divmod(round(self.core.time * 1e9), 1_000_000_000)
            return Time(sec=sec, nanosec=nanosec)
        return self.get_clock().now().to_msg()

    def publish_clock_now(self) -> None:
        """Publish /clock at the world's time, serialized here.

        It is the world's busiest publisher (116 Hz to every node): a Python Clock message per
        sample cost more than the bytes.
        """
        self.clock_pub.publish(clock_cdr(round(self.core.time * 1e9)))

    def publish_step(self, out: dict) -> None:
        """Publish what one core step produced."""
        if self.s.publish_clock and self.core.sample % self.s.clock_every == 0:
            self.publish_clock_now()
        for name, fields in out['records'].items():
            self.out[name].publish(fields)
        if self.core.bumper != self._bumper:  # the bumper switch, to traction
            self._bumper = self.core.bumper
            self.bumper_pub.publish(Bool(data=self._bumper))
        for event in out['events']:
            self.out['world_event'].publish({**{k: event[k] for k in (
                'event', 'marker_kind', 'identity', 'error', 'speed', 'lateral', 'count',
                'station')}, 'time_ms': round(event['time'] * 1000) & 0xFFFF})
        pose_due = self.core.sample % self._pose_every == 0
        stamp = self.stamp() if out['frames'] or pose_due else None
        for name, frame in out['frames'].items():
            self.camera_pubs[name].publish(camera_image(frame, name, stamp))
        if pose_due:
            x, y, h, _v = self.core.pose()
            self.pose_pub.publish(pose_message(x, y, h, stamp))

    # -- the loop ---------------------------------------------------------------------------
    def drain(self, executor: Any, limit: int = 200) -> None:
        """Run every callback that is ready now (inputs, services)."""
        for _ in range(limit):
            before = self._work
            executor.spin_once(timeout_sec=0.0)
            if self._work == before:
                return

    def _wait_for_peers(self, executor: Any) -> bool:
        started = time.monotonic()
        while running() and self.peers.missing():
            if self.s.publish_clock:
                self.publish_clock_now()
            executor.spin_once(timeout_sec=0.05)
            if time.monotonic() - started > self.s.peer_timeout:
                self.get_logger().error(f'peers not matched after {self.s.peer_timeout:.0f} s '
                                        f'(links still missing: {self.peers.missing()})')
                return False
        self.get_logger().info(f'layout {self.layout.name}: moving at time_factor '
                               f'{self.s.time_factor:g} ({len(self.peers.links)} links matched '
                               f'at both ends after {time.monotonic() - started:.2f} s)')
        if self.s.ready_file:
            Path(self.s.ready_file).write_text(f'moving at sim time {self.core.time:.3f} s\n')
        return True

    def _catch_up(self, executor: Any) -> None:
        """Let lagging nodes catch up before time moves on (at most lag_patience)."""
        late = self.pacer.lagging(self.core.time)
        waited = time.monotonic()
        nudge = waited + 0.05
        while late and running() and time.monotonic() - waited < self.s.lag_patience:
            executor.spin_once(timeout_sec=0.002)
            late = self.pacer.lagging(self.core.time)
            if late and self.s.publish_clock and time.monotonic() > nudge:
                # The same time again: a node that missed the last /clock gets another look;
                # timers that already ran at this time do not run twice.
                self.publish_clock_now()
                nudge = time.monotonic() + 0.05
        if late and running():  # (not when a stop request ended the wait)
            self.pacer.give_up(late)
            self.get_logger().warn(f'carrying on without {", ".join(late)} (behind for '
                                   f'{self.s.lag_patience:g} s)')

    def _report_pacing(self) -> None:
        """Log how far behind the world each node was heard at worst over the last minute."""
        worst = ', '.join(f'{name} {s * 1000:.0f} ms' for name, s in
                          sorted(self.pacer.worst.items()))
        self.get_logger().info(f'pacing, the last minute: worst behind {worst or "-"}')
        self.pacer.worst.clear()

    def run(self, executor: Any) -> int:
        """Wait for peers, then step the world until shut down (or `duration`)."""
        if not self._wait_for_peers(executor):
            return 1
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
            if self.pacer.lagging(self.core.time):
                self._catch_up(executor)
                wall0, sim0 = time.monotonic(), self.core.time
            self.publish_step(self.core.step())
            if self.s.duration and self.core.time >= self.s.duration:
                self.get_logger().info(f'duration {self.s.duration:g} s reached')
                return 0
            if self.s.time_factor > 0:
                ahead = (self.core.time - sim0) / self.s.time_factor - (time.monotonic() - wall0)
                if ahead > 0:
                    time.sleep(ahead)
        return 0


def main(args: list[str] | None = None) -> int:
    """Entry point: ros2 run agv_nodes world [--ros-args ...]."""
    return spin_main(WorldNode, args, run=lambda node, executor: node.run(executor))


if __name__ == '__main__':
    sys.exit(main())
