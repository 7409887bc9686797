"""DDS discovery on one host for graphs of any size the launcher makes (up to 120 processes).

`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` has rmw_fastrtps announce each participant to the
first 32 participant ports of its domain only. Every process of a graph is a participant, so a
graph of more than 32 (a fleet of four trucks is 36 with the demo, one of eight 68) never
discovers those that started last: the world, started last, goes unheard, no /clock reaches
the dispatcher, and nothing moves. The Fast DDS profile `config/dds/localhost_discovery.xml`
keeps that setting's reach (loopback unicast only, no multicast, no other interface) and
announces to 120 participants, all a domain's block of ports holds. It takes
`ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`: any other range has rmw_fastrtps replace the
profile's transports with its own.

The launcher gives this environment to every process it starts; the demos, benchmarks and tests
set it on themselves before their first participant (Fast DDS reads the profile once per
process). Across hosts, give the processes `ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET` instead
(docs/hardware.md).
"""

from __future__ import annotations

from collections.abc import MutableMapping
import os

from agv_nodes.package_share import share_dir

PROFILE = 'localhost_discovery.xml'  # in config/dds/
PARTICIPANTS = 120  # the profile's maxInitialPeersRange
RANGE = 'SYSTEM_DEFAULT'  # leaves the profile's transports as they are
# Fast DDS 2.x reads the first; 3.x the second.
PROFILE_VARIABLES = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')


def profile_path() -> str:
    """Return the path of the localhost discovery profile of this install."""
    return str(share_dir() / 'config' / 'dds' / PROFILE)


def localhost_environment() -> dict[str, str]:
    """Return the variables giving a process localhost-only discovery for 120 participants."""
    profile = profile_path()
    return {'ROS_AUTOMATIC_DISCOVERY_RANGE': RANGE,
            **dict.fromkeys(PROFILE_VARIABLES, profile)}


def use_localhost_discovery(environ: MutableMapping[str, str] = os.environ) -> None:
    """Set localhost discovery in `environ` (this process's: before its first participant)."""
    environ.update(localhost_environment())
    environ.pop('ROS_LOCALHOST_ONLY', None)  # the old switch would override the range
