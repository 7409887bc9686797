"""The lock-step harness's public names: every one the docs name is there, and an old one warns.

The names come from the docs themselves (docs/*.md and README.md: `harness.NAME` and imports
from agv_nodes.harness), so a rename that forgets the docs fails here. `truck(world_params=...)`
is the keyword scripts used before `overrides` (git log -S world_params): it stays one release,
warning and naming its successor.
"""

from __future__ import annotations

import inspect
from pathlib import Path
import re
import warnings

import pytest

from agv_nodes import harness
from agv_nodes.settings import values_of
from agv_nodes.world.settings import ElectrukParams, WorldParams

REPO = Path(__file__).resolve().parents[1]
# `harness.truck()`, `agv_nodes.harness.run_for`; not the file name harness.py
DOTTED = re.compile(r'\bharness\.([A-Za-z_]\w*)(?![\w.]*\.py)')
IMPORTED = re.compile(r'from agv_nodes\.harness import \(?([\w ,\n]+)\)?')


def documented_names() -> dict[str, list[str]]:
    """Name -> the doc files that name it, from every markdown file the project documents in."""
    names: dict[str, list[str]] = {}
    for doc in sorted([*REPO.glob('docs/*.md'), REPO / 'README.md']):
        text = doc.read_text()
        found = set(DOTTED.findall(text))
        for group in IMPORTED.findall(text):
            found.update(n.strip() for n in group.replace('\n', ',').split(',') if n.strip())
        for name in found - {'py'}:
            names.setdefault(name, []).append(doc.name)
    return names


@pytest.mark.timeout(30)
def test_every_harness_name_the_docs_give_is_importable():
    names = documented_names()
    # architecture.md documents the whole-truck builder by this name (read, not assumed)
    assert 'truck' in names, names
    missing = {n: where for n, where in names.items() if not hasattr(harness, n)}
    assert not missing, f'named in the docs but not in agv_nodes.harness: {missing}'
    assert callable(harness.truck)


@pytest.mark.timeout(30)
def test_truck_keeps_its_documented_keywords():
    params = inspect.signature(harness.truck).parameters
    for name in ('seed', 'overrides', 'params_file', 'integrity', 'world_params'):
        assert name in params and params[name].kind is inspect.Parameter.KEYWORD_ONLY, name


@pytest.mark.timeout(120)
def test_world_params_warns_naming_overrides_and_still_sets_the_world():
    wp = WorldParams(seed=3, electruk=ElectrukParams(payload=1000.0))
    with pytest.warns(DeprecationWarning, match=r"world_params.*overrides=\{'world'"):
        h = harness.truck('straight_track', seed=3, world_params=wp)
    # the world runs with that WorldParams whole, as the keyword gave it before
    assert values_of(h.world.p) == values_of(wp)
    assert h.world.p.electruk.payload == 1000.0
    h.run(0.2)  # it steps
    # the new name gives the same world, and says nothing
    with warnings.catch_warnings():
        warnings.simplefilter('error', DeprecationWarning)
        new = harness.truck('straight_track', seed=3,
                            overrides={'world': values_of(wp)})
    assert values_of(new.world.p) == values_of(h.world.p)


@pytest.mark.timeout(120)
def test_overrides_win_over_world_params():
    wp = WorldParams(seed=3, electruk=ElectrukParams(payload=1000.0))
    with pytest.warns(DeprecationWarning):
        h = harness.truck('straight_track', world_params=wp,
                          overrides={'world': {'electruk.payload': 500.0}})
    assert h.world.p.electruk.payload == 500.0 and h.world.p.seed == 3
