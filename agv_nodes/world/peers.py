"""Before the world moves: every link of the graph matched at both ends (graph/links).

Each node announces which inputs have matched a writer and how many readers each output has matched
(agv_nodes.ros_ports.LinkAnnouncer); the world waits for `wait_for_links`: 'NODE:RECORD' (NODE's
reader has matched the writer) and 'NODE>RECORD:N' (NODE's writer has matched N readers). Why:
docs/architecture.md, "Start-up".
"""

from collections.abc import Callable, Mapping

from rclpy.node import Node
from std_msgs.msg import String

from agv_nodes import qos, sim_progress
from agv_nodes.records import codec
from agv_nodes.ros_ports import LINKS_TOPIC, parse_links


def parse_link_entry(entry: str) -> tuple[str, str, int | None] | None:
    """'NODE:RECORD' -> (node, record, None), 'NODE>RECORD:N' (or progress) -> N; else None.

    'clock' stands for /clock: 'world>clock:N' (the world's writer), 'recorder:clock' (the
    recorder's reader, announced by the recorder).
    """
    if '>' in entry:
        node, _, rest = entry.partition('>')
        record, _, count = rest.partition(':')
        readers = int(count) if count.isdigit() and int(count) > 0 else None
        if not node or readers is None or (record not in codec() and record not in (
                sim_progress.LINK, sim_progress.CLOCK_LINK)):
            return None
        return node, record, readers
    node, _, record = entry.partition(':')
    known = record in codec() or record == sim_progress.CLOCK_LINK
    return (node, record, None) if node and known else None


class LinkWatch:
    """The world's view of which links have matched: its own ends, the others' announcements."""

    def __init__(self, node: Node, links: list[tuple[str, str, int | None]],
                 own_readers: Mapping[str, Callable[[], int]],
                 own_writers: Mapping[str, Callable[[], int]]) -> None:
        self._node = node
        self.links = links
        self._own_readers = own_readers  # record -> its writers matched
        self._own_writers = own_writers  # record -> its readers matched
        self._inputs: dict[str, set[str]] = {}  # node -> its inputs matched
        self._outputs: dict[str, dict[str, int]] = {}  # node -> readers its outputs matched
        node.create_subscription(String, LINKS_TOPIC, self._on_links, qos.LINKS_READER)

    def _on_links(self, msg: String) -> None:
        name, inputs, outputs = parse_links(msg.data)
        self._inputs[name], self._outputs[name] = inputs, outputs

    def missing(self) -> list[str]:
        """Links not matched yet."""
        me = self._node.get_name()
        missing = []
        for node, record, readers in self.links:
            if readers is not None:  # the writer's end
                if node == me:
                    count_of = self._own_writers.get(record)
                    count = count_of() if count_of is not None else 0
                else:
                    count = self._outputs.get(node, {}).get(record, 0)
                if count < readers:
                    missing.append(f'{node}>{record}:{readers} (has {count})')
            elif node == me:
                count_of = self._own_readers.get(record)
                if count_of is None or count_of() == 0:
                    missing.append(f'{node}:{record}')
            elif record not in self._inputs.get(node, ()):
                missing.append(f'{node}:{record}')
        return missing
