"""The ctypes take through librcl (agv_nodes/rclpy_internals.py) against the installed rclpy.

Each message must come with the GID the graph shows for its writer, in order, whole (a message
larger than the first buffer included), under both executors a node may run; where librcl
cannot be used, the reader falls back to rclpy's take and says so.
"""

from __future__ import annotations

import time

import pytest

pytestmark = [pytest.mark.wall_clock, pytest.mark.timeout(60)]


# Record readers and nodes a test made through _a_record_from_an_intruder: destroyed before
# their context shuts down. Left to the garbage collector, a reader's writer-tagged
# subscription (no subscription of its node's, so destroy_node leaves it) was finalised in a
# later test, where Fast DDS's delete_datareader waited for ever on its event thread.
MADE: list = []


@pytest.fixture
def context():
    import rclpy

    ctx = rclpy.Context()
    rclpy.init(context=ctx)  # the session's own domain (test/conftest.py)
    yield ctx
    while MADE:  # readers first, then their nodes
        made = MADE.pop(0)
        if hasattr(made, 'schema'):
            made.destroy()
        else:
            made.destroy_node()
    rclpy.try_shutdown(context=ctx)


@pytest.mark.parametrize('kind', ['events', 'single'])
def test_each_message_comes_with_its_writers_graph_gid_in_order(context, kind):
    import rclpy
    from rclpy.serialization import serialize_message
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos
    from agv_nodes.rclpy_internals import writer_identity_unavailable, writer_tagged_subscription

    if kind == 'events':
        from rclpy.experimental import EventsExecutor
        executor = EventsExecutor(context=context)
    else:
        executor = rclpy.executors.SingleThreadedExecutor(context=context)
    assert writer_identity_unavailable() == ''
    reader = rclpy.create_node('tagged_reader', context=context)
    writers = [rclpy.create_node(f'tagged_writer_{k}', context=context) for k in range(2)]
    got: list[tuple[bytes, bytes, int]] = []
    sub = writer_tagged_subscription(reader, UInt8MultiArray, 'tagged', qos.RECORD_READER,
                                     lambda *sample: got.append(sample))
    assert sub is not None and sub.handle not in [s.handle for s in reader.subscriptions]
    pubs = [w.create_publisher(UInt8MultiArray, 'tagged', qos.RECORD_WRITER) for w in writers]
    executor.add_node(reader)
    deadline = time.monotonic() + 10
    while sub.publisher_count() < 2:  # handshake: both writers matched before anything is sent
        executor.spin_once(timeout_sec=0.05)
        assert time.monotonic() < deadline, 'writers not matched'
    sent = []
    for k in range(20):
        msg = UInt8MultiArray(data=bytes([k]) * (16 if k != 7 else 5000))  # 7: past the buffer
        sent.append((serialize_message(msg), k % 2))
        pubs[k % 2].publish(msg)
    deadline = time.monotonic() + 10
    while len(got) < 20 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    graph = {bytes(i.endpoint_gid): i.node_name
             for i in reader.get_publishers_info_by_topic('tagged')}
    assert [raw for raw, _gid, _t in got] == [raw for raw, _w in sent]
    assert [graph[gid] for _raw, gid, _t in got] == [f'tagged_writer_{w}' for _r, w in sent]
    assert all(abs(stamp * 1e-9 - time.time()) < 30 for _r, _g, stamp in got)  # wall ns
    executor.shutdown()
    sub.destroy()
    for node in (reader, *writers):
        node.destroy_node()


def _a_record_from_an_intruder(context, reader: str, second_reader: bool = False):
    """Return (subscription, records taken) of node `reader` after node `intruder` sent one."""
    import rclpy

    from agv_nodes.records import codec
    from agv_nodes.ros_ports import RecordPublisher, RecordSubscription

    node = rclpy.create_node(reader, context=context)
    intruder = rclpy.create_node('intruder', context=context)
    MADE.extend((node, intruder))
    schema = codec()['traction_command']
    got: list[dict] = []
    sub = RecordSubscription(node, schema, callback=got.append)
    MADE.insert(0, sub)
    if second_reader:
        MADE.insert(0, RecordSubscription(node, codec()['traction_status']))
    pub = RecordPublisher(intruder, schema)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    deadline = time.monotonic() + 10
    while sub.publisher_count() < 1 or pub.subscription_count < 1:
        executor.spin_once(timeout_sec=0.05)
        assert time.monotonic() < deadline
    pub.publish({'demand': 10})
    while not got and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.shutdown()
    return sub, got


def test_without_librcl_the_reader_takes_through_rclpy_and_says_the_check_is_off(
        context, monkeypatch, capsys):
    from agv_nodes import rclpy_internals

    monkeypatch.setattr(rclpy_internals, '_libraries', lambda: 'librcl.so: not found')
    rclpy_internals.writer_identity_unavailable.cache_clear()
    try:
        # a second reader: the check being off is said once
        sub, got = _a_record_from_an_intruder(context, 'executive', second_reader=True)
        assert got and got[0]['demand'] == 10  # no identity check: any writer is heard
        assert sub.identity() == 'not checked: librcl.so: not found'
        assert capsys.readouterr().err.count('record writer identity check off') == 1
    finally:
        rclpy_internals.writer_identity_unavailable.cache_clear()


def test_a_message_info_not_laid_out_as_expected_turns_the_check_off(context, monkeypatch):
    """Where the GID is not where Jazzy has it, a reader hears every writer and says so."""
    from agv_nodes import rclpy_internals

    monkeypatch.setattr(rclpy_internals.WriterTaggedSubscription, '_check_layout',
                        lambda self: False)
    sub, got = _a_record_from_an_intruder(context, 'traction')
    assert got and sub.rejected == 0
    assert sub.identity().startswith('not checked: the message info is not laid out')


def test_a_tagged_subscription_goes_with_its_context_not_with_the_garbage_collector():
    """Its node destroyed or not, a context's shutdown frees the tagged subscription at once.

    destroy_node cannot (the subscription is not the node's), and what the collector finalises
    at some later collection can hang Fast DDS's delete_datareader.
    """
    import rclpy
    from std_msgs.msg import UInt8MultiArray

    from agv_nodes import qos
    from agv_nodes.rclpy_internals import writer_tagged_subscription

    for destroy_node_first in (True, False):
        ctx = rclpy.Context()
        rclpy.init(context=ctx)
        node = rclpy.create_node('tagged_shutdown', context=ctx)
        sub = writer_tagged_subscription(node, UInt8MultiArray, 'tagged_shutdown',
                                         qos.RECORD_READER, lambda *_s: None)
        assert sub is not None and sub.waitable in list(node.waitables)
        if destroy_node_first:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        assert sub._destroyed and sub.waitable not in list(node.waitables)
        with pytest.raises(Exception, match='destruction was requested'):
            sub.publisher_count()  # the handle is gone, not waiting for a collection
        sub.destroy()  # a second time: nothing
