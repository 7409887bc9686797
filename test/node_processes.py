"""Node processes seen from a test: alive or not, and on the DDS graph yet.

Shared by the tests that kill a launcher (test_kill_dds.py, test_launch_vda5050_dds.py).
"""

from __future__ import annotations


def wait_until_on_the_graph(count: int, timeout: float, namespace: str) -> None:
    """Wait until `count` nodes are on the domain in `namespace`: each is past die_with_parent.

    The namespace is the test's own: nodes of an earlier test on the same domain (a SIGKILLed
    one's stay in DDS discovery for seconds) must not count.

    A node asks for its parent-death signal in spin_main, before rclpy.init: one seen on the
    graph has asked. A parent killed before that, while the node still imports, is not the
    fault the kill tests are about (the node is not running yet), and how long the imports
    take is the machine's business, so they wait for the nodes rather than for a fixed time.
    """
    import time

    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    probe = None
    try:
        probe = rclpy.create_node('node_processes_probe', context=context,
                                  start_parameter_services=False)
        deadline = time.monotonic() + timeout
        others: list[str] = []
        while time.monotonic() < deadline:
            others = [n for n, ns in probe.get_node_names_and_namespaces() if ns == namespace]
            if len(others) >= count:
                return
            time.sleep(0.1)
        raise AssertionError(f'{count} nodes expected in {namespace} within {timeout:g} s, '
                             f'saw {others}')
    finally:
        # destroyed here, not by the collector: a reader finalized later, at some other test's
        # garbage collection, can hang in Fast DDS's delete_datareader (seen in a full run)
        if probe is not None:
            probe.destroy_node()
        rclpy.try_shutdown(context=context)


def alive(pid: int) -> bool:
    """Return True while process `pid` exists and is not a zombie."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[1].split()[0] != 'Z'
    except FileNotFoundError:
        return False
