"""A full disk while recording: the recording stops, the truck does not notice.

The whole graph runs with the recorder (one process per node over DDS, as agv-demo runs it).
Once the truck cruises on its task, the test lowers the recorder's `space_limit` to a little
above what its bag file holds: the next commits meet it as a full disk (OSError ENOSPC,
raised where os.pwrite would raise it, agv_nodes/bag_file.py). Then:

- the recorder's /diagnostics row `agv/recorder/bag` turns ERROR and says why, and its output
  (the launcher's log of it) has the line;
- the truck's nodes run on: the task completes, no process dies, and the recorder exits
  cleanly when the launch stops it;
- the bag file reads, with the `mcap` reader and with rosbags, to its last commit: exactly the
  messages the recorder's row counts as committed, the last of them stamped before the stop.

The bag file's own part (bag_file.CommittedFile) is tested first without DDS: a commit that
meets the limit, partly written, leaves the file as the commit before.
"""

from __future__ import annotations

import errno
from pathlib import Path

from graph_probe import GraphProbe
import pytest

from agv_nodes.bag_file import CommittedFile

HEADER, TAIL = b'HEADER', b'SUMMARY+FOOTER'

HEADROOM = 20_000  # bytes above the file's size when the limit is lowered: a commit or two


def _committed(tmp_path, limit: int) -> tuple[CommittedFile, bytes]:
    """Return a CommittedFile after one commit of 100 data bytes, and the file then."""
    raw = open(tmp_path / 'bag.mcap', 'xb')  # noqa: SIM115 - closed by the CommittedFile
    raw.write(HEADER)  # as rosbags' writer opens a bag
    bag_file = CommittedFile(raw, limit)
    bag_file.write(b'a' * 100)
    bag_file.mark()
    bag_file.write(TAIL)
    bag_file.close()
    return bag_file, HEADER + b'a' * 100 + TAIL


@pytest.mark.timeout(30)
@pytest.mark.parametrize('room', [10, 0, -50])  # bytes the next commit finds; < 0: limit lowered
def test_a_commit_that_meets_a_full_disk_leaves_the_last_commit(tmp_path, room):
    bag_file, before = _committed(tmp_path, 0)
    assert (tmp_path / 'bag.mcap').read_bytes() == before
    bag_file.space_limit = len(before) + room
    bag_file.write(b'b' * 100)
    bag_file.mark()
    bag_file.write(TAIL + b'2')
    with pytest.raises(OSError) as info:
        bag_file.close()
    assert info.value.errno == errno.ENOSPC
    assert (tmp_path / 'bag.mcap').read_bytes() == before
    bag_file.abandon()


@pytest.mark.timeout(30)
def test_a_commit_within_the_limit_is_written_whole(tmp_path):
    bag_file, before = _committed(tmp_path, 0)
    bag_file.space_limit = len(before) + 100 + len(TAIL)  # exactly room for the next commit
    bag_file.write(b'b' * 100)
    bag_file.mark()
    bag_file.write(TAIL)
    bag_file.close()
    assert (tmp_path / 'bag.mcap').read_bytes() == HEADER + b'a' * 100 + b'b' * 100 + TAIL
    bag_file.abandon()


@pytest.mark.dds
@pytest.mark.slow
@pytest.mark.timeout(400)
def test_a_full_disk_stops_the_recording_and_not_the_truck(tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    from agv_nodes import qos

    bag = tmp_path / 'bag'
    g = GraphProbe(tmp_path / 'logs', bag=bag)
    rows: list[tuple[int, str, dict[str, str], float]] = []  # recorder rows, sim time seen

    def on_row(msg: DiagnosticArray) -> None:
        rows.extend((int.from_bytes(s.level, 'little'), s.message,
                     {kv.key: kv.value for kv in s.values}, g.time)
                    for s in msg.status if s.name == 'agv/recorder/bag')

    g.node.create_subscription(DiagnosticArray, '/diagnostics', on_row, qos.EVENTS)
    try:
        g.start_task('stop at 2 first')  # returns once the truck cruises
        mcap_file = bag / f'{bag.name}.mcap'  # rosbags names the file after the bag
        limit = mcap_file.stat().st_size + HEADROOM
        g.set_parameters('recorder', space_limit=limit)
        g.spin_until(lambda: rows and rows[-1][0] == 2, 60, 'the recorder to stop')
        level, message, values, stopped_at = rows[-1]
        assert message.startswith(f'recording stopped: No space left on device (space_limit '
                                  f'{limit} bytes) writing {bag}'), message
        assert 'the truck runs on' in message
        assert g.speed > 0.1, 'the disk filled after the truck had stopped'
        # the truck's task goes on to its end
        g.report_with("'stop at 2 first': completed", wall_limit=180)
        assert not [line for line in g.reports if 'FAILED' in line], g.reports
        g.spin_until(lambda: rows[-1][2]['messages not recorded'] != '0', 10,
                     'messages taken after the stop')
        committed = int(rows[-1][2]['messages committed'])
        assert int(values['messages committed']) == committed  # nothing committed after
        assert not g.launch.poll() and not g.launch.failed
    finally:
        g.close()
    assert g.launch.exits.get('recorder') == 0, g.launch.exits
    said = '\n'.join(g.launch.lines)
    assert 'recording stopped: No space left on device' in said, said[-3000:]
    assert 'bag closed early: recording stopped' in said, said[-3000:]

    # (not "no larger than the limit": the limit may arrive below what was committed by then,
    # set_parameters waits for the service; the commit after fails, and the file stays)
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == committed
        stamps = [m.log_time for _s, _c, m in reader.iter_messages()]
    assert len(stamps) == committed > 0
    with AnyReader([bag]) as reader:
        assert sum(1 for _ in reader.messages()) == committed
    assert max(stamps) * 1e-9 <= stopped_at + 1.0  # sim stamps: none from after the stop
    assert Path(bag / 'metadata.yaml').exists() and not (bag / 'metadata.yaml.tmp').exists()
