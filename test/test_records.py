"""Record codec: every thesis value of Baker 1983, 6.2.3-6.3.1 encodes and decodes to its bytes."""

from __future__ import annotations

import pytest
from record_values import field_value

from agv_nodes.records import RecordError, Reject, codec
from agv_nodes.records.e2e import crc8_sae_j1850, record_crc

C = codec()


def plain(record: str, **fields) -> bytes:
    """Pack a plain thesis record (integrity none): bytes 15-16 are 00H."""
    return C.encode(record, fields, integrity='none')


def test_crc8_sae_j1850_check_value():
    assert crc8_sae_j1850(b'123456789') == 0x4B
    assert crc8_sae_j1850(b'') == 0x00  # init FF, xorout FF, no data


# -- navigation_status: fig 6.2, the values PC6/1 writes (Baker 1983, App. B.1) -------------------
@pytest.mark.parametrize('byte1, fields', [
    (0x0A, dict(at_location=0, slow=1, reverse=0, lost=1)),  # power-up
    (0x00, dict(at_location=0, slow=0, reverse=0, lost=0)),  # OPLOP: navigating
    (0x03, dict(at_location=1, slow=1, reverse=0, lost=0)),  # CLOP: positioning
    (0x0B, dict(at_location=1, slow=1, reverse=0, lost=1)),  # centre stop view
])
def test_navigation_status_thesis_byte1(byte1, fields):
    raw = plain('navigation_status', last_marker=0x02, **fields)
    assert raw[0] == byte1
    assert raw[1:3] == b'\x02\x00'
    decoded = C.decode('navigation_status', raw, integrity='none')
    assert {k: decoded[k] for k in fields} == fields


def test_navigation_status_power_up_is_0A_FF():
    raw = plain('navigation_status')  # schema defaults = the power-up record
    assert raw[:3] == bytes([0x0A, 0xFF, 0x00])
    assert raw[3:] == bytes(13)
    fields = C.decode('navigation_status', raw, integrity='none')
    assert fields['last_marker'] == 0xFF
    assert C['navigation_status'].describe(fields)['last_marker'] == 'none seen yet'


def test_navigation_status_step_table_of_spec_4():
    """The task 'stop at location 2, first stop marker' record sequence (Baker 1983, App. B.1)."""
    steps = [
        (dict(), 0x0A, 0xFF),
        (dict(slow=0, lost=0, last_marker=0), 0x00, 0x00),
        (dict(slow=0, lost=0, last_marker=1), 0x00, 0x01),
        (dict(at_location=1, slow=1, lost=0, last_marker=2), 0x03, 0x02),
        (dict(at_location=1, slow=1, lost=1, last_marker=2), 0x0B, 0x02),
    ]
    for fields, b1, b2 in steps:
        raw = plain('navigation_status', **fields)
        assert (raw[0], raw[1]) == (b1, b2)


# -- traction_link: Baker 1983, 6.3.1 -----------------------------------------------------------
@pytest.mark.parametrize('value, fields', [
    (0x40, dict(executive_priority=1, reverse=0, speed=0)),  # OPLOP
    (0x14, dict(executive_priority=0, reverse=0, speed=20)),  # SLOW1
    (0x00, dict(executive_priority=0, reverse=0, speed=0)),  # SETPT / centre view
    (0x34, dict(executive_priority=0, reverse=1, speed=20)),  # overshoot reverse (Baker 1983, 8.5)
])
def test_traction_link_values(value, fields):
    raw = plain('traction_link', **fields)
    assert raw[0] == value and raw[1:] == bytes(15)  # a plain 1983 one-byte link
    assert C.decode('traction_link', raw, integrity='none') == {**fields, 'stop_in': 0}


def test_traction_link_bit7_is_spare():
    with pytest.raises(RecordError) as info:
        C.decode('traction_link', bytes([0x80]) + bytes(15), integrity='none')
    assert info.value.byte == 1 and 'spare' in str(info.value)


# -- traction_command: Baker 1983, App. B.2.2  ----------------------------------------------------
def test_traction_command_byte2_zero_is_emergency_stop():
    raw = bytes(16)
    fields = C.decode('traction_command', raw, integrity='none')
    assert fields['demand'] == 0 and fields['manual'] == 0
    assert C['traction_command'].describe(fields)['demand'].startswith('EMERGENCY STOP')


@pytest.mark.parametrize('demand, byte2', [(20, 0x14), (-5, 0xFB), (80, 0x50), (-80, 0xB0)])
def test_traction_command_demand_twos_complement(demand, byte2):
    raw = plain('traction_command', demand=demand)
    assert raw[1] == byte2
    assert C.decode('traction_command', raw, integrity='none')['demand'] == demand


def test_traction_command_manual_byte1_whole():
    """Manual: byte 1 bit 0 = 1, bits 1-6 speed, bit 7 reverse (REF = byte 1 as signed)."""
    raw = plain('traction_command', manual=1, manual_speed=10, reverse=1)
    assert raw[0] == 0x80 | (10 << 1) | 1
    assert C.decode('traction_command', raw, integrity='none') == dict(
        manual=1, manual_speed=10, reverse=1, demand=0, executive_priority=0)


def test_traction_command_demand_beyond_80_rejected():
    raw = bytearray(16)
    raw[1] = 0x51  # +81 % is no armature duty the board can give
    with pytest.raises(RecordError) as info:
        C.decode('traction_command', raw, integrity='none')
    assert (info.value.byte, info.value.field, info.value.value) == (2, 'demand', 81)


# -- navigation_command: Baker 1983, App. B.1  ----------------------------------------------------
def test_navigation_command_location_and_edge():
    assert plain('navigation_command', task_location=2, stop_marker=0)[:2] == b'\x02\x00'
    assert plain('navigation_command', task_location=2, stop_marker=1)[:2] == b'\x02\x01'
    assert plain('navigation_command')[:2] == b'\xff\x00'  # no task
    with pytest.raises(RecordError):
        C.decode('navigation_command', b'\x02\x02' + bytes(14), integrity='none')  # byte 2 bit 1


# -- E2E bytes 15-16 ------------------------------------------------------------------------
def test_e2e_counter_and_crc_bytes():
    s = C['navigation_status']
    raw = s.encode({}, counter=7)
    assert raw[14] == 7
    assert raw[15] == record_crc(s.data_id, raw[:15])
    assert raw[15] == crc8_sae_j1850(bytes([0x12]) + raw[:15])
    assert s.decode(raw) == s.defaults()


def test_e2e_crc_covers_data_id():
    """The same bytes under another record's data_id fail: a record on the wrong topic."""
    raw = C.encode('navigation_command', {'task_location': 1}, counter=3)
    with pytest.raises(RecordError) as info:
        C.decode('load_command', raw)
    assert info.value.byte == 16


def test_integrity_none_requires_bytes_15_16_zero():
    raw = C.encode('navigation_status', {}, counter=1)
    with pytest.raises(RecordError) as info:
        C.decode('navigation_status', raw, integrity='none')
    assert info.value.byte == 15


def test_hardware_records_use_all_16_bytes_unprotected():
    fields = {f'lit_{d}': 100 + d for d in range(1, 9)}
    fields.update({f'dark_{d}': 200 + d for d in range(1, 9)})
    raw = C.encode('adc_snapshot', fields)
    assert raw == bytes([101, 102, 103, 104, 105, 106, 107, 108,
                         201, 202, 203, 204, 205, 206, 207, 208])
    assert C.decode('adc_snapshot', raw) == fields
    assert not C['adc_snapshot'].protected


# -- error messages name record, byte, field and value --------------------------------------
@pytest.mark.parametrize('record, data, integrity, byte, field, words', [
    ('navigation_status', bytes(15), 'none', None, None, 'length 15'),
    ('navigation_status', bytes(17), 'none', None, None, 'length 17'),
    ('navigation_status', bytes([0x0A, 0xFF, 0, 0, 0, 0, 0, 0x01]) + bytes(8), 'none', 8, None,
     'spare'),
    ('navigation_status', bytes([0x1A, 0xFF]) + bytes(14), 'none', 1, None, 'spare'),
    ('navigation_status', bytes([0x0A, 0x40]) + bytes(14), 'none', 2, 'last_marker',
     'out of range'),
    ('position_sensor_command', bytes([0x02]) + bytes(15), 'none', 1, 'table', 'unknown enum'),
    ('traction_drive', bytes([81]) + bytes(15), 'none', 1, 'armature_duty', 'out of range'),
])
def test_decode_errors_name_the_place(record, data, integrity, byte, field, words):
    with pytest.raises(RecordError) as info:
        C.decode(record, data, integrity=integrity)
    err = info.value
    assert err.record == record and err.byte == byte and err.field == field
    assert words in str(err) and record in str(err)
    if byte is not None:
        assert f'byte {byte}' in str(err)


def test_encode_errors_name_the_place():
    with pytest.raises(RecordError, match="route_command byte 1 field 'mode': unknown enum"):
        C.encode('route_command', {'mode': 'reverse_wire'})
    with pytest.raises(RecordError, match="field 'speed': value out of range"):
        C.encode('traction_link', {'speed': 32})
    with pytest.raises(RecordError, match="field 'sped'"):
        C.encode('traction_link', {'sped': 3})
    with pytest.raises(RecordError, match='no such record'):
        C.encode('traction_links', {})


def _crc_flipped(record: str) -> bytes:
    raw = bytearray(C.encode(record, {}, counter=4))
    raw[15] ^= 0x01
    return bytes(raw)


@pytest.mark.parametrize('record, data, integrity, code', [
    ('navigation_status', bytes(15), 'none', Reject.WRONG_LENGTH),
    ('navigation_status', bytes(17), 'e2e', Reject.WRONG_LENGTH),
    ('traction_command', _crc_flipped('traction_command'), 'e2e', Reject.BAD_CRC),
    ('traction_link', bytes([0x80]) + bytes(15), 'none', Reject.SPARE_SET),
    ('navigation_status', bytes([0x0A, 0xFF]) + bytes(12) + b'\x01\x00', 'none',
     Reject.SPARE_SET),  # byte 15 without E2E
    ('wheel_odometry', bytes(15) + b'\x01', 'none', Reject.SPARE_SET),  # hardware spare byte
    ('traction_command', bytes([0, 0x51]) + bytes(14), 'none', Reject.BAD_VALUE),
    ('traction_drive', bytes([81]) + bytes(15), 'none', Reject.BAD_VALUE),
    ('position_sensor_command', bytes([0x02]) + bytes(15), 'none', Reject.BAD_VALUE),
])
def test_decode_errors_carry_their_reject_code(record, data, integrity, code):
    """Ports count rejections by `code`, never by the wording of the message."""
    from agv_nodes.records.ports import CORRUPT, RecordReader

    with pytest.raises(RecordError) as info:
        C.decode(record, data, integrity=integrity)
    assert info.value.code is code and code.value in CORRUPT
    reader = RecordReader(C[record], integrity=integrity)
    assert reader.accept(data, 0) is None
    assert dict(reader.rejects) == {code.value: 1} and reader.last_reason == code.value


def test_caller_errors_carry_their_reject_code():
    cases = [
        (lambda: C.encode('traction_link', {'sped': 3}), Reject.UNKNOWN_FIELD),
        (lambda: C['traction_link'].field('sped'), Reject.UNKNOWN_FIELD),
        (lambda: C.encode('traction_links', {}), Reject.UNKNOWN_RECORD),
        (lambda: C.encode('traction_link', {}, integrity='crc'), Reject.UNKNOWN_INTEGRITY),
        (lambda: C.decode('traction_link', bytes(16), integrity='crc'),
         Reject.UNKNOWN_INTEGRITY),
        (lambda: C.encode('traction_link', {}, counter=256), Reject.BAD_VALUE),
        (lambda: C.encode('traction_link', {'speed': 32}), Reject.BAD_VALUE),
        (lambda: C.encode('traction_link', {'speed': 1.0}), Reject.BAD_VALUE),
        (lambda: C.encode('route_command', {'mode': 'reverse_wire'}), Reject.BAD_VALUE),
    ]
    for call, code in cases:
        with pytest.raises(RecordError) as info:
            call()
        assert info.value.code is code, str(info.value)


def test_reject_codes_are_the_diagnostics_counter_keys():
    from agv_nodes.records.ports import CORRUPT

    assert CORRUPT == {'bad_crc', 'wrong_length', 'spare_set', 'bad_value'}
    assert all(type(key) is str for key in CORRUPT)
    assert Reject('bad_crc') is Reject.BAD_CRC and Reject.BAD_CRC.value == 'bad_crc'


def test_every_schema_names_topic_writer_readers_and_thesis():
    names = C.names()
    assert len(names) == 22
    for s in C:
        assert s.topic and not s.topic.startswith('/')
        assert s.writer and s.readers and s.thesis
        for f in s.fields:
            assert f.thesis, f'{s.name}.{f.name} has no thesis reference'
    assert sorted({s.data_id for s in C}) == sorted(s.data_id for s in C)


def test_port_declarations_from_schemas():
    reads, writes = C.for_node('navigation')
    assert {s.name for s in reads} == {'navigation_command', 'position_sensor_status',
                                       'wheel_odometry'}
    assert {s.name for s in writes} == {'navigation_status', 'traction_link',
                                        'position_sensor_command'}


def test_inputs_report_counts_rejections_by_reason_and_warns_while_they_arrive():
    from agv_nodes.records.ports import RecordReader, RecordWriter, inputs_report

    schema = codec()['traction_command']
    reader, writer = RecordReader(schema), RecordWriter(schema)
    good = writer.pack({'demand': 20})
    assert reader.accept(good, 0) is not None
    level, message, values = inputs_report({'traction_command': reader})
    assert level == 0 and values['rejected'] == '0' and 'inputs valid' in message
    assert reader.accept(good[:15], 1) is None  # wrong length
    assert reader.accept(good, 2) is None  # the same counter again
    level, message, values = inputs_report({'traction_command': reader})
    assert level == 1 and values['traction_command rejected'] == '2'
    assert values['traction_command rejects by reason'] == 'repeated_counter=1, wrong_length=1'
    level, message, _ = inputs_report({'traction_command': reader}, rejected_before=2)
    assert level == 0 and '2 rejected in all' in message


def test_inputs_report_puts_the_nodes_own_verdict_first():
    from agv_nodes.records.ports import RecordReader, inputs_report
    from agv_nodes.traction.core import TractionCore

    core = TractionCore()
    core.tripped = False  # armed and running ...
    core._trip('stale_command')  # ... until the executive fell silent
    level, message, values = inputs_report({'traction_command': RecordReader(
        codec()['traction_command'])}, now_ns=10**9, health=core.health())
    assert level == 2 and message.startswith('trip relay open: stale_command (the executive')
    assert values['traction_command age (s)'] == 'never'
    assert TractionCore().health()[0] == 1  # tripped at start-up: a warning, not a fault


def test_carriers_read_and_written_straight_as_cdr():
    """The serialized carriers (agv_nodes.records.carrier) agree with rosbags' (de)serializer.

    The nodes' and agv-report's carriers give exactly what rosbags' (de)serializer gives, and
    decline (None: the general path) any message they do not fully understand.
    """
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from agv_nodes.records.carrier import (
        clock_cdr,
        clock_ns,
        uint8_array_cdr,
        uint8_array_data,
    )

    store = get_typestore(Stores.ROS2_JAZZY)
    msg_type = 'std_msgs/msg/UInt8MultiArray'
    array, layout = store.types[msg_type], store.types['std_msgs/msg/MultiArrayLayout']
    dim = store.types['std_msgs/msg/MultiArrayDimension']
    for data in (bytes(range(16)), b'', bytes(range(15)), bytes([0xFF] * 40)):
        raw = store.serialize_cdr(array(layout=layout(dim=[], data_offset=0),
                                        data=np.frombuffer(data, dtype=np.uint8)), msg_type)
        assert uint8_array_data(raw) == data
        assert uint8_array_data(memoryview(raw)) == data
        assert uint8_array_data(raw[:-1]) is None  # truncated
        assert uint8_array_cdr(data) == raw  # what the nodes publish
        assert bytes(store.deserialize_cdr(raw, msg_type).data) == data
    with_dims = store.serialize_cdr(array(layout=layout(dim=[dim(label='x', size=16, stride=16)],
                                                        data_offset=0),
                                          data=np.arange(16, dtype=np.uint8)), msg_type)
    assert uint8_array_data(with_dims) is None
    big_endian = b'\x00\x00\x00\x00' + bytes(28)  # CDR_BE encapsulation
    assert uint8_array_data(big_endian) is None
    clock = store.types['rosgraph_msgs/msg/Clock']
    time = store.types['builtin_interfaces/msg/Time']
    for sec, nanosec in ((0, 0), (381, 999_999_999), (2**31 - 1, 5)):
        raw = store.serialize_cdr(clock(clock=time(sec=sec, nanosec=nanosec)),
                                  'rosgraph_msgs/msg/Clock')
        assert clock_ns(raw) == sec * 1_000_000_000 + nanosec
        assert clock_cdr(sec * 1_000_000_000 + nanosec) == bytes(raw)  # what the world sends
    assert clock_ns(b'\x00\x00\x00\x00' + bytes(8)) is None  # big endian
    assert clock_ns(bytes(raw[:11])) is None
    # ClockTimers and the recorder read /clock through ros_ports.clock_time_ns: the CDR the
    # world sends directly, a big-endian writer's through rclpy's deserializer
    from agv_nodes.ros_ports import clock_time_ns

    assert clock_time_ns(clock_cdr(381_000_000_007)) == 381_000_000_007
    big = b'\x00\x00\x00\x00' + (381).to_bytes(4, 'big') + (7).to_bytes(4, 'big')
    assert clock_ns(big) is None and clock_time_ns(big) == 381_000_000_007


def test_a_record_in_any_layout_is_read_from_its_cdr():
    """The nodes' readers take records serialized, in any layout.

    The shape they send is read straight from the CDR, any other layout (a driver's dims, a
    data_offset) through rclpy's deserializer, and both give the 16 bytes.
    """
    from rclpy.serialization import serialize_message
    from std_msgs.msg import MultiArrayDimension, MultiArrayLayout, UInt8MultiArray

    from agv_nodes.records.carrier import uint8_array_cdr, uint8_array_data
    from agv_nodes.ros_ports import record_bytes

    data = bytes(range(100, 116))
    plain = serialize_message(UInt8MultiArray(data=data))
    assert plain == uint8_array_cdr(data) and record_bytes(plain) == data
    dims = MultiArrayLayout(dim=[MultiArrayDimension(label='bytes', size=16, stride=16)],
                            data_offset=3)
    for layout in (dims, MultiArrayLayout(data_offset=3)):
        raw = serialize_message(UInt8MultiArray(layout=layout, data=data))
        assert uint8_array_data(raw) is None  # not the shape the nodes send
        assert record_bytes(raw) == data


def test_compiled_fast_paths_agree_with_the_field_by_field_codec():
    """The generated fast paths agree with the general loop and take the common cases.

    Encode / decode try generated straight-line code first (records.schema.compile_fast_paths) and
    fall back to the general loop on None: whatever the fast path returns must be exactly what
    the general path makes of the same input, and the fast path must take the common cases.
    """
    import random

    rng = random.Random(11)
    for s in codec():
        pack, unpack = s._compiled
        taken = {'pack': 0, 'unpack': 0}
        for i in range(400):
            # every fourth all valid: with twenty fields a mostly-valid draw is rarely valid
            values = {f.name: field_value(f, rng, valid=i % 4 == 0) for f in s.fields
                      if rng.random() < 0.9}
            fast = pack(values)
            try:
                general = s._encode_fields(values)
            except RecordError:
                assert fast is None, (s.name, values)
                continue
            if fast is not None:
                taken['pack'] += 1
                assert fast == general, (s.name, values)
        for _ in range(400):
            data = bytes(rng.randrange(256) if rng.random() < 0.5 else rng.choice((0, 255))
                         for _ in range(16))
            fast = unpack(data)
            try:
                general = s._decode_fields(data)
            except RecordError:
                assert fast is None, (s.name, data.hex())
                continue
            assert fast == general, (s.name, data.hex())
            taken['unpack'] += 1
        # every valid record takes the fast path (above: general succeeded => fast agreed)
        valid = s.defaults()
        assert pack(valid) is not None
        assert unpack(s.encode(valid, integrity='none' if not s.protected else 'e2e')) \
            is not None
        assert taken['pack'] > 0, s.name
