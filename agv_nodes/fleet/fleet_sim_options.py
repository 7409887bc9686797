"""agv-fleet-sim's command-line options, checked: one line naming the option, value and way on.

Layouts: a name from config/layouts (fleet_1983 by default, eight parking places), a layout
file, or `fleet_1983_n<N>`: the fleet floor lengthened to park N trucks
(agv_nodes.world.fleet_floor), written to a temporary directory for the run.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
import re
import tempfile
from typing import Any

from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.mqtt.broker import EmbeddedBroker, broker_url, local_broker
from agv_nodes.mqtt.mosquitto import Mosquitto
from agv_nodes.vda5050 import INTERFACE
from agv_nodes.vda5050.topics import topic
from agv_nodes.world.fleet_floor import extension_for, fleet_floor_text
from agv_nodes.world.layout import Layout, LayoutError, layout_path, load_layout

MANUFACTURER = 'agv_nodes'
MAX_STATE_INTERVAL = 30.0  # s: VDA 5050 6.10 asks for a state at least this often
_FLOOR = re.compile(r'fleet_1983_n(\d{1,3})')


@dataclass(frozen=True)
class SimOptions:
    """What a fleet simulator runs (checked by options_from_args)."""

    layout: str = 'fleet_1983'  # a layout name or file
    serials: tuple[str, ...] = ('agv1',)
    starts: tuple[str, ...] = ('A1.1',)  # stop markers, one per truck
    manufacturer: str = MANUFACTURER
    interface: str = INTERFACE
    time_factor: float = 1.0  # simulated s per wall s; 0: as fast as it goes
    processes: int = 1
    seed: int = 1
    state_interval: float = MAX_STATE_INTERVAL
    visualization_period: float = 1.0  # simulated s
    status_period: float = 5.0  # wall s


def parser() -> argparse.ArgumentParser:
    """Return the command line's parser."""
    p = argparse.ArgumentParser(
        prog='agv-fleet-sim', description='N whole lock-step trucks, each a VDA 5050 AGV on '
        'one MQTT broker, for a master control of your own (docs/fleet_simulator.md).')
    p.add_argument('--mqtt-url', help='the broker, mqtt://host:port (default: AGV_MQTT_URL, '
                   'else a local broker on a free port: mosquitto, or amqtt where it is not '
                   'installed)')
    p.add_argument('--layout', default='fleet_1983',
                   help='layout name or file; fleet_1983_n<N> writes a floor parking N trucks')
    p.add_argument('--trucks', type=int, default=2, help='how many trucks (default 2)')
    p.add_argument('--serials', help='their serial numbers, comma-separated (default agv1..N)')
    p.add_argument('--starts', help="their start stop markers, comma-separated (default: the "
                   "layout's parking places)")
    p.add_argument('--manufacturer', default=MANUFACTURER)
    p.add_argument('--interface', default=INTERFACE, help="the topics' first level (uagv)")
    p.add_argument('--time-factor', type=float, default=1.0,
                   help='simulated s per wall s (default 1; 0: as fast as it goes)')
    p.add_argument('--processes', type=int, help='processes stepping the trucks (default: '
                   'the cores, at most one per truck)')
    p.add_argument('--seed', type=int, default=1)
    p.add_argument('--state-interval', type=float, default=MAX_STATE_INTERVAL,
                   help='simulated s between states without a change (at most 30)')
    p.add_argument('--visualization-period', type=float, default=1.0,
                   help='simulated s between visualization messages')
    p.add_argument('--status-period', type=float, default=5.0,
                   help='wall s between status lines and messages')
    p.add_argument('--seconds', type=float, help='stop after this much simulated time')
    return p


def floor_file(name: str) -> str:
    """Return the layout to load for `name`: fleet_1983_n<N> is written to a temporary file."""
    match = _FLOOR.fullmatch(name)
    if match is None or layout_path(name).exists():
        return name
    trucks = int(match[1])
    path = Path(tempfile.mkdtemp(prefix='agv-fleet-sim-')) / f'{name}.yaml'
    path.write_text(fleet_floor_text(name, extension_for(trucks), trucks), encoding='utf-8')
    return str(path)


def start_of(layout: Layout, marker: str) -> tuple[str, float]:
    """Return (path, at) of stop marker `marker`; ValueError names the stop markers."""
    stops = {m.name: (m.path, m.at) for m in layout.markers if m.kind == 'stop'}
    if marker not in stops:
        raise ValueError(f'{marker!r} is no stop marker of layout {layout.name} (stop '
                         f'markers: {", ".join(sorted(stops))})')
    return stops[marker]


def _bad(option: str, value: Any, why: str) -> ValueError:
    return ValueError(f'--{option} {value}: {why}')


def _checked(args: argparse.Namespace, cpus: int) -> SimOptions:
    if args.trucks < 1:
        raise _bad('trucks', args.trucks, 'give 1 or more')
    try:
        layout = load_layout(layout_path(floor_file(args.layout)))
    except (LayoutError, FileNotFoundError, OSError) as exc:
        raise _bad('layout', args.layout, f'{exc}'.splitlines()[0]) from None
    if layout.vehicle != 'electruk' or layout.kind != 'wire':
        raise _bad('layout', args.layout, 'the fleet runs on a wire layout of the Electruk '
                   '(fleet_1983, loops_1983, demo_1983, fleet_1983_n<N>)')
    serials = tuple(args.serials.split(',')) if args.serials else \
        tuple(f'agv{k + 1}' for k in range(args.trucks))
    if len(serials) != args.trucks or len(set(serials)) != len(serials):
        raise _bad('serials', args.serials, f'give {args.trucks} different serial numbers')
    for serial in (args.manufacturer, *serials):
        try:
            topic(args.manufacturer, serial, 'state', interface=args.interface)
        except ValueError as exc:
            raise _bad('serials' if serial in serials else 'manufacturer', serial,
                       str(exc)) from None
    starts = tuple(args.starts.split(',')) if args.starts else tuple(layout.parking)
    if args.starts and len(starts) != args.trucks:
        raise _bad('starts', args.starts, f'give {args.trucks} stop markers, one per truck')
    if len(starts) < args.trucks:
        raise _bad('trucks', args.trucks, f'layout {layout.name} parks {len(starts)}; give '
                   f'--starts or --layout fleet_1983_n{args.trucks}')
    starts = starts[:args.trucks]
    stops = {n for n, node in track_graph(layout).nodes.items() if node.stoppable}
    for marker in starts:
        if marker not in stops:
            raise _bad('starts', args.starts, f'{marker!r} is no stop marker of {layout.name}')
    if len(set(starts)) != len(starts):
        raise _bad('starts', args.starts, 'two trucks at one marker')
    if args.time_factor < 0:
        raise _bad('time-factor', args.time_factor, 'give 0 (as fast as it goes) or more')
    processes = args.processes or min(cpus, args.trucks)
    if not 1 <= processes <= args.trucks:
        raise _bad('processes', args.processes, f'give 1 to {args.trucks} (the trucks)')
    if not 0 < args.state_interval <= MAX_STATE_INTERVAL:
        raise _bad('state-interval', args.state_interval, 'give more than 0 and at most 30 s '
                   '(VDA 5050 6.10)')
    for option in ('visualization_period', 'status_period'):
        if not getattr(args, option) > 0:
            raise _bad(option.replace('_', '-'), getattr(args, option), 'give more than 0 s')
    if args.seconds is not None and not args.seconds > 0:
        raise _bad('seconds', args.seconds, 'give more than 0 s')
    return SimOptions(str(layout.file), serials, starts, args.manufacturer, args.interface,
                      args.time_factor, processes, args.seed, args.state_interval,
                      args.visualization_period, args.status_period)


def options_from_args(args: argparse.Namespace, cpus: int
                      ) -> tuple[SimOptions, str, Mosquitto | EmbeddedBroker | None]:
    """Return the checked options, the broker's URL and the local broker started, if any.

    The local broker is mosquitto where it is installed, else the embedded amqtt (as
    agv-launch's).

    ValueError says in one line which option and value is wrong and what to give.
    """
    options = _checked(args, cpus)
    url = broker_url(args.mqtt_url)
    if url is not None:
        return options, url, None
    broker = local_broker()
    return options, broker.start(), broker
