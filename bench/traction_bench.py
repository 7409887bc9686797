"""Traction benchmark: speed steps on the world core, open loop (1983) and closed loop.

A stand-in executive commands a demand step on straight_track; traction drives the simulated
Electruk. Printed: time to 90 % of the final speed, overshoot, 2 % settling time and steady
speed, unloaded and with 1000 kg.

Run: .venv/bin/python bench/traction_bench.py
"""

from __future__ import annotations

import sys

from agv_nodes.harness import Harness
from agv_nodes.traction.core import TractionCore
from agv_nodes.traction.settings import TractionParams
from agv_nodes.world.core import WorldCore
from agv_nodes.world.layout import layout_path, load_layout
from agv_nodes.world.settings import ElectrukParams, WorldParams


class Executive:
    node, period = 'executive', 0.05

    def __init__(self) -> None:
        self.demand = 0

    def on_record(self, *args):
        return None

    def tick(self, now):
        return {'traction_command': dict(manual=0, manual_speed=0, reverse=0,
                                         demand=self.demand, executive_priority=0)}


class Steering:
    node, period = 'route_following', 0.01

    def on_record(self, *args):
        return None

    def tick(self, now):
        return {'steering_command': dict(mode='angle', enable=1, angle=0, left_speed=0,
                                         right_speed=0)}


def step(control: str, demand: int, payload: float) -> dict:
    world = WorldCore(load_layout(layout_path('straight_track')),
                      WorldParams(seed=1, electruk=ElectrukParams(payload=payload)))
    ex = Executive()
    h = Harness(world, [ex, TractionCore(TractionParams(control=control)), Steering()])
    h.run(0.3)
    ex.demand = 1  # 00H then non-zero: clears traction's start-up trip
    h.run(0.5)
    ex.demand = demand
    t0, trace = h.now, []
    while h.now - t0 < 15:
        h.step()
        trace.append((h.now - t0, world.vehicle.state.speed))
    final = sum(v for _t, v in trace[-340:]) / 340
    peak = max(v for _t, v in trace)
    rise = next(t for t, v in trace if v >= 0.9 * final)
    settle = max((t for t, v in trace if abs(v - final) > 0.02 * final), default=0.0)
    return {'final': final, 'overshoot': 100 * (peak - final) / final, 'rise': rise,
            'settle': settle}


def main() -> int:
    print('| control | demand (%) | payload (kg) | steady speed (m/s) | 90 % rise (s) | '
          'overshoot (%) | 2 % settle (s) |')
    print('|---|---|---|---|---|---|---|')
    for control in ('open_loop_1983', 'closed_loop'):
        for demand in (20, 55, 80):
            for payload in (0.0, 1000.0):
                r = step(control, demand, payload)
                print(f'| {control} | {demand} | {payload:.0f} | {r["final"]:.3f} | '
                      f'{r["rise"]:.2f} | {r["overshoot"]:.1f} | {r["settle"]:.2f} |',
                      flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
