"""The graph description (config/graph.yaml): each node's script, module, role and realtime."""

from dataclasses import dataclass
from pathlib import Path

from agv_nodes.package_share import config_dir, read_mapping

NODE_KEYS = frozenset({'name', 'executable', 'module', 'role', 'realtime', 'trucks'})
ROLES = ('node', 'world', 'recorder', 'bridge', 'master', 'viewer')
TRUCKS = ('electruk', 'concic2')  # the vehicles a layout names (agv_nodes/world/layout.py)


class GraphError(ValueError):
    """A graph description or launch option that cannot be used (names the file, key, value)."""


@dataclass
class NodeSpec:
    """One node of the graph."""

    name: str
    executable: str
    module: str
    role: str = 'node'
    realtime: bool = False  # on the sensor-to-traction chain: SCHED_FIFO with --realtime
    trucks: tuple[str, ...] = TRUCKS  # the trucks that have this node


@dataclass
class Graph:
    """The graph description."""

    name: str
    nodes: list[NodeSpec]
    parameters: Path
    file: Path

    def node(self, name: str) -> NodeSpec:
        """Return the node called `name`."""
        return next(n for n in self.nodes if n.name == name)

    def for_truck(self, vehicle: str) -> 'Graph':
        """Return the graph of one truck: the nodes it has (`trucks`)."""
        return Graph(self.name, [n for n in self.nodes if vehicle in n.trucks], self.parameters,
                     self.file)


def load_graph(file: Path | None = None) -> Graph:
    """Load and check config/graph.yaml (or another description)."""
    file = Path(file) if file else config_dir() / 'graph.yaml'
    doc = read_mapping(file, GraphError, ('graph', 'parameters', 'nodes'))
    if not isinstance(doc.get('nodes'), list):
        raise GraphError(f'{file}: key nodes: a list of nodes is required')
    nodes = []
    for i, spec in enumerate(doc['nodes']):
        if not isinstance(spec, dict):
            raise GraphError(f'{file}: key nodes[{i}]: {spec!r} must be a mapping')
        if extra := set(spec) - NODE_KEYS:
            raise GraphError(f'{file}: key nodes[{i}].{sorted(extra)[0]}: unknown key')
        for key in ('name', 'executable', 'module'):
            if not isinstance(spec.get(key), str) or not spec[key]:
                raise GraphError(f'{file}: key nodes[{i}].{key}: {spec.get(key)!r} missing')
        if (role := spec.get('role', 'node')) not in ROLES:
            raise GraphError(f'{file}: key nodes[{i}].role: {role!r} not one of {ROLES}')
        if not isinstance(realtime := spec.get('realtime', False), bool):
            raise GraphError(f'{file}: key nodes[{i}].realtime: {realtime!r} is not true/false')
        trucks = spec.get('trucks', list(TRUCKS))
        if not isinstance(trucks, list) or not trucks or set(trucks) - set(TRUCKS):
            raise GraphError(f'{file}: key nodes[{i}].trucks: {trucks!r} is not a list of '
                             f'{", ".join(TRUCKS)}')
        nodes.append(NodeSpec(spec['name'], spec['executable'], spec['module'], role, realtime,
                              tuple(trucks)))
    params = file.parent / str(doc.get('parameters', 'agv_demo.yaml'))
    return Graph(str(doc.get('graph', 'agv')), nodes, params, file)
