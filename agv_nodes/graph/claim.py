"""Claiming a ROS domain and namespace for one graph: a second graph there is refused.

Two graphs on one domain and namespace (a second agv-launch, or nodes left running) would have
their nodes interleave: each reader would follow whichever writer its graph shows first. So a
launch claims its (domain, namespace) before it starts a process:

- a lock file per (domain, namespace) in /tmp (flock, released when the launcher ends however
  it ends): a second launcher of this host's users finds it held;
- the live graph: a graph started without the lock (another host user whose lock file this user
  cannot open, nodes started by hand, an older launcher) is found by looking. First, cheaply,
  whether any DDS participant of another process is on the domain at all: each one binds its
  unicast discovery port, 7400 + 250 * domain + 10 + 2 * participant (the RTPS port mapping
  Fast DDS and Cyclone DDS follow), and /proc/net/udp lists every socket of the host's network
  namespace, whoever owns it. Only when there is one does the launcher join the domain for a
  discovery wait (`LOOK_S`) and ask the graph for the node names of its own units.

Cost, measured on the development machine (two cores, shared): on a domain no other process
uses, 2 ms (median of 20 claims; the lock and /proc/net/udp); with another namespace's graph on
the domain, the discovery wait, 0.7 to 3.5 s.

With no domain given, the launcher takes the first domain whose lock is free and that no other
process's participant uses.
"""

from __future__ import annotations

from collections.abc import Iterable
import fcntl
import os
from pathlib import Path
import time
from typing import TextIO

from agv_nodes.graph.model import GraphError

LOCK_DIR = Path('/tmp')
PORT_BASE, DOMAIN_GAIN = 7400, 250  # the RTPS port mapping (DDSI-RTPS 2.5, 9.6.1.1)
# Longest wait for another graph's nodes to show, once another process's participant is on the
# domain. A running participant answers a newcomer at its next periodic announcement (Fast DDS:
# every 3 s), so a newcomer on a busy two-core machine saw one executive's node after 0.7-2.8 s
# (/agv2 claimed beside /agv1, a fresh process each, load average 5-7).
LOOK_S = 3.5
HELD_LOOK_S = 5.0  # ... when its launcher holds the lock: the refusal names them
SETTLE_S = 0.5  # after one of them shows, for the others to show too


def _socket_inodes(pid: str = 'self') -> set[str]:
    inodes = set()
    fd_dir = Path(f'/proc/{pid}/fd')
    try:
        for fd in fd_dir.iterdir():
            try:
                target = os.readlink(fd)
            except OSError:
                continue
            if target.startswith('socket:['):
                inodes.add(target[8:-1])
    except OSError:
        pass
    return inodes


def participant_ports(domain: int, exclude_own: bool = True) -> list[int]:
    """Return the UDP ports of `domain`'s block that some process binds (not this one's).

    Empty where /proc/net/udp cannot be read (not Linux): the look then always joins.
    """
    low = PORT_BASE + DOMAIN_GAIN * domain
    own = _socket_inodes() if exclude_own else set()
    ports = []
    for table in ('/proc/net/udp', '/proc/net/udp6'):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            cols = line.split()
            port = int(cols[1].rsplit(':', 1)[1], 16)
            if low <= port < low + DOMAIN_GAIN and cols[9] not in own:
                ports.append(port)
    return sorted(ports)


def proc_net_readable() -> bool:
    """Return True where the host's sockets can be listed (/proc/net/udp)."""
    return Path('/proc/net/udp').is_file()


def participants(ports: Iterable[int], domain: int) -> int:
    """Return how many participants bind `ports`: one unicast discovery port each."""
    low = PORT_BASE + DOMAIN_GAIN * domain + 10
    return len({p for p in ports if p >= low and (p - low) % 2 == 0})


def live_nodes(domain: int, wanted: Iterable[tuple[str, str]], look_s: float = LOOK_S,
               others: int = 0) -> list[str]:
    """Join `domain` for at most `look_s` s; return the full names of `wanted` nodes found.

    `wanted`: (namespace, name) pairs, namespace as the graph shows it ('/' or '/agv2'). The
    look ends early once every wanted node shows, or once as many nodes as there are `others`
    (participants of other processes: each ROS process has a node at least) show and none of
    them is wanted. Its own participant is in a context of its own, gone before this returns;
    the process's discovery settings are the launcher's (agv_nodes.discovery).
    """
    import rclpy
    from rclpy.context import Context

    from agv_nodes.discovery import use_localhost_discovery

    wanted = set(wanted)
    use_localhost_discovery()
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    found: list[str] = []
    try:
        node = rclpy.create_node('agv_launch_claim', context=context,
                                 start_parameter_services=False, enable_rosout=False)
        deadline = time.monotonic() + look_s
        while time.monotonic() < deadline and len(found) < len(wanted):
            seen = [(ns, name) for name, ns in node.get_node_names_and_namespaces()
                    if name != 'agv_launch_claim']
            now = sorted(f'{ns.rstrip("/")}/{name}' for ns, name in seen if (ns, name) in wanted)
            if not now and others and len(seen) >= others:
                break  # every other process's nodes have shown: none of this graph's
            if now != found:  # the others show over the next moments
                found, deadline = now, max(deadline, time.monotonic() + SETTLE_S)
            time.sleep(0.02)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    return found


def lock_path(domain: int, namespace: str) -> Path:
    """Return the lock file of (domain, namespace)."""
    ns = namespace.strip('/').replace('/', '+') or '+'
    return LOCK_DIR / f'agv_nodes_graph_{domain}_{ns}.lock'


def lock_graph(domain: int, namespace: str) -> tuple[TextIO | None, str]:
    """Take (domain, namespace)'s lock: (its handle, '') or (None, who holds it).

    A lock file another user made, which this user cannot open, is left to the live look.
    """
    path = lock_path(domain, namespace)
    try:
        handle = open(path, 'a+')  # noqa: SIM115 - held while the graph runs
    except OSError:
        return None, ''
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.seek(0)
        holder = handle.read().strip() or '?'
        handle.close()
        return None, f'launcher pid {holder} holds {path}'
    handle.seek(0)
    handle.truncate()
    handle.write(f'{os.getpid()}\n')
    handle.flush()
    return handle, ''


def claim_graph(domain: int, namespace: str,
                units: Iterable[tuple[str, str]]) -> TextIO | None:
    """Claim (domain, namespace) for a graph of `units` (namespace, node name); its lock.

    GraphError in one line when a graph runs there: the domain, the namespace, the nodes
    found and how to go on.
    """
    units = list(units)
    handle, holder = lock_graph(domain, namespace)
    found: list[str] = []
    ports = participant_ports(domain)
    if handle is None or ports or not proc_net_readable():
        # this process's own nodes (a test's probe) would count among the others
        own = set(participant_ports(domain, exclude_own=False)) - set(ports)
        found = live_nodes(domain, units, LOOK_S if handle is not None else HELD_LOOK_S,
                           0 if own else participants(ports, domain))
    if handle is None and holder or found:
        if handle is not None:
            handle.close()
        where = namespace or '/'
        raise GraphError(
            f'a graph already runs on ROS_DOMAIN_ID={domain}, namespace {where}: '
            f'{"nodes " + ", ".join(found) if found else "no nodes seen yet"}'
            f'{"; " + holder if holder else ""}; to start another, give it another '
            '--domain-id (ROS_DOMAIN_ID) or --namespace')
    return handle


def claim_domain(explicit: int | None = None) -> tuple[int, TextIO | None]:
    """Claim a ROS domain id for this graph: explicit, ROS_DOMAIN_ID, or a free one by lock.

    A free one: its lock free and no other process's participant on it (participant_ports).
    """
    if explicit is None and os.environ.get('ROS_DOMAIN_ID'):
        explicit = int(os.environ['ROS_DOMAIN_ID'])
    if explicit is not None:
        if not 1 <= explicit <= 232:
            raise GraphError(f'domain id {explicit}: use 1-232 (never 0: other graphs on this '
                             'host may be on it)')
        return explicit, None
    start = 1 + os.getpid() % 200
    for i in range(232):
        domain = 1 + (start + i - 1) % 232
        try:  # another user's lock file cannot be opened: that user's domain
            handle = open(LOCK_DIR / f'agv_nodes_ros_domain_{domain}.lock', 'w')  # noqa: SIM115
        except OSError:
            continue
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        if participant_ports(domain):  # in use without the lock (another user's graph)
            handle.close()
            continue
        return domain, handle
    raise GraphError('no free ROS domain id 1-232 on this host')
