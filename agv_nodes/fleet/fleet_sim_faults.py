"""The faults agv-fleet-sim injects into one truck of its lock-step fleet, and their clearing.

Each runs in the process that steps the truck (Fleet.query: module functions, so they pickle),
on the truck's lock-step harness, between two world samples:

- `drive`: the line from the executive to traction is cut (every traction_command lost, as
  the harness's link faults lose records). Traction trips on the stale command after its
  command_timeout and opens the trip relay; the executive sees the trip in traction_status,
  e-stops and fails the running task ("FAILED: tripped"), which the bridge reports as the
  order's error. Cleared: the line carries records again; the relay stays open until the
  executive's next task resets it, as on the truck (Baker 1983, B.2.1).
- `radioStop`: the radio-control stop input (hw/radio_stop) set, as the operator's handset
  sets it: the world cuts the drive and traction reports it ("FAILED: radio stop").
- `blockedMarker`: one marker card covered for this truck: its world's marker sensor sees the
  floor without it (as the world node's `remove_markers` removes one from the whole floor).
  What follows is the truck's own: a missed stop marker ends at the positioning limit.

The fourth fault, `brokerLink`, is the truck's MQTT link and is done by its VDA 5050 face
(agv_nodes.fleet.fleet_sim_truck), not here.
"""

from __future__ import annotations

import dataclasses

from agv_nodes.harness import Harness, Link

DRIVE_LINE = 'traction_command'  # the record the drive fault loses


def drive(h: Harness, on: bool) -> None:
    """Cut (on) or mend the executive's command line to traction."""
    if on:
        h.links[DRIVE_LINE] = Link(drop=1.0)
    else:
        h.links.pop(DRIVE_LINE, None)


def radio_stop(h: Harness, on: bool) -> None:
    """Set or release the truck's radio stop."""
    h.set_radio_stop(on)


def blocked_marker(h: Harness, on: bool, marker: str) -> None:
    """Cover (on) or uncover marker `marker` for this truck's sensor; KeyError: no such marker.

    The world keeps the floor's whole layout aside and reads a copy without the covered cards;
    its cache of the cards near the lens is emptied, so the change holds from the next sample.
    """
    world = h.world
    floor = world.__dict__.setdefault('floor_layout', world.layout)
    covered: set[str] = world.__dict__.setdefault('covered_markers', set())
    names = sorted(m.name for m in floor.markers)
    if marker not in names:
        raise KeyError(f'no marker {marker!r} on the floor ({", ".join(names)})')
    if on:
        covered.add(marker)
    else:
        covered.discard(marker)
    world.layout = dataclasses.replace(
        floor, markers=[m for m in floor.markers if m.name not in covered])
    # the world's cards-near-the-lens cache (agv_nodes.world.ground_truth) indexes the markers
    world.truth.forget_cards()


def state(h: Harness) -> dict[str, object]:
    """Return the truck's injected faults now (for the simulator's status)."""
    world = h.world
    return {'drive': DRIVE_LINE in h.links, 'radioStop': world.radio_stop,
            'blockedMarker': sorted(world.__dict__.get('covered_markers', ())),
            'pose': world.pose()}


def pose(h: Harness) -> tuple[float, float, float, float]:
    """Return the truck's ground-truth (x, y, heading, speed) of the world's vehicle point."""
    return h.world.pose()


def reference_pose(h: Harness) -> tuple[float, float, float, float]:
    """Return the ground truth of the truck's reference point, for its visualization.

    The world's vehicle point is the driven (rear) axle centre; the reference point of the
    factsheet's geometry and of agvPosition is the front axle centre, where the guide-wire
    coils and the marker sensor are (agv_nodes.vda5050.truck_factsheet; VDA 5050 6.7: the
    vehicle reference point is the origin of the vehicle frame the factsheet describes).
    """
    _x, _y, heading, speed = h.world.pose()
    x, y = h.world.vehicle.sensor_point
    return x, y, heading, speed
