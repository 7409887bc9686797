"""agv-launch refuses a second graph on a domain and namespace where one runs (graph/claim.py).

A second `agv-launch` on the domain of a running graph (ROS_DOMAIN_ID set, as the test session
sets it) ends at once with one line naming the domain, the namespace, the nodes found and the way
on, and a non-zero status; the first graph runs on undisturbed (every process alive, each node
once on the graph, its truck still takes a task). Nodes started without any launcher (no lock
held) are found on the live graph and refused the same way. Another namespace on the same
domain is free.
"""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from graph_probe import GraphProbe
from node_processes import wait_until_on_the_graph
import pytest

from agv_nodes.discovery import use_localhost_discovery
from agv_nodes.graph.parameters import Options
from agv_nodes.graph.supervisor import Launch

pytestmark = [pytest.mark.dds, pytest.mark.slow]

STRAY = ('executive', 'traction')


def agv_launch(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    """Run agv-launch on the session's domain (ROS_DOMAIN_ID) with a stop after 20 s."""
    return subprocess.run([sys.executable, '-m', 'agv_nodes.graph.cli', '--duration', '20',
                           *args], capture_output=True, text=True, timeout=timeout,
                          env=dict(os.environ))


@pytest.mark.timeout(300)
def test_a_second_launch_on_a_running_graph_is_refused_in_one_line(tmp_path):
    domain = os.environ['ROS_DOMAIN_ID']
    g = GraphProbe(tmp_path / 'logs')
    try:
        g.ready()
        launched = [label for label, _s, _n in g.launch.units()]  # config/graph.yaml's
        second = agv_launch()
        out = (second.stdout + second.stderr).strip().splitlines()
        assert second.returncode != 0 and len(out) == 1, (second.returncode, out)
        line = out[0]
        assert line.startswith(f'agv-launch: a graph already runs on ROS_DOMAIN_ID={domain}, '
                               'namespace /: nodes '), line
        named = line.split(': nodes ', 1)[1].split(';', 1)[0].split(', ')
        # those its discovery wait found: the graph's own, at least the first to show
        assert named and set(named) <= {f'/{label}' for label in launched}, line
        assert 'holds' in line and '--domain-id' in line and '--namespace' in line, line
        # the first graph: undisturbed
        assert not g.launch.poll(), g.launch.lines[-20:]
        names = g.node.get_node_names_and_namespaces()
        ours = [n for n, ns in names if ns == '/' and n in launched]
        assert sorted(ours) == sorted(launched), names  # each once: no second graph
        g.start_task('stop at 2 second')
        assert not g.launch.poll()
        # another namespace on the same domain is free (claimed, not started)
        other = Launch(Options(quiet=True, namespace='/agv_other', domain_id=int(domain)))
        other.claim()
        other.stop()
    finally:
        g.close()


@pytest.mark.timeout(120)
def test_nodes_started_without_a_launcher_are_found_on_the_live_graph(tmp_path):
    env = dict(os.environ)
    use_localhost_discovery(env)
    bin_dir = Path(sys.executable).parent
    procs = [subprocess.Popen([str(bin_dir / node), '--ros-args', '-p', 'use_sim_time:=true',
                               '-r', '__ns:=/stray'], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL) for node in STRAY]
    try:
        wait_until_on_the_graph(len(STRAY), 60, '/stray')
        second = agv_launch('--namespace', '/stray')
        out = (second.stdout + second.stderr).strip().splitlines()
        assert second.returncode != 0 and len(out) == 1, (second.returncode, out)
        line = out[0]
        domain = os.environ['ROS_DOMAIN_ID']
        assert line.startswith(f'agv-launch: a graph already runs on ROS_DOMAIN_ID={domain}, '
                               'namespace /stray: nodes '), line
        named = line.split(': nodes ', 1)[1].split(';', 1)[0].split(', ')
        assert named and set(named) <= {f'/stray/{n}' for n in STRAY}, line
        assert 'holds' not in line, line  # no launcher: found by looking
        assert all(p.poll() is None for p in procs)
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=10)

