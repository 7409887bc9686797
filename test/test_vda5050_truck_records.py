"""The truck's records into BridgeCore (agv_nodes.vda5050.truck_records), one fact at a time.

Each record is packed and judged by the record codec from msg_schemas/ (the writer's and a
reader's ports), as the bridge node takes it off DDS, and the state the bridge then sends is
read back from its JSON against the official 2.1.0 state schema. What a field means comes
from the record tables (msg_schemas/*.yaml) and the standard (6.10.6), not from the bridge.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from jsonschema.validators import validator_for
import pytest

from agv_nodes.fleet.track_graph import track_graph
from agv_nodes.records import codec
from agv_nodes.records.ports import RecordReader, RecordWriter
from agv_nodes.vda5050.bridge import BridgeCore
from agv_nodes.vda5050.codec import to_json
from agv_nodes.world.layout import layout_path, load_layout

pytestmark = pytest.mark.timeout(60)

SCHEMA = json.loads((Path(__file__).parent / 'data' / 'vda5050_2.1.0' / 'state.schema')
                    .read_text(encoding='utf-8'))


class Records:
    """A writer and a reader per record, as the truck's node and the bridge have them."""

    def __init__(self) -> None:
        self.ports = {}
        for schema in codec():
            mode = 'e2e' if schema.protected else 'none'
            self.ports[schema.name] = (RecordWriter(schema, mode), RecordReader(schema, mode))
        self.core = BridgeCore(track_graph(load_layout(layout_path('demo_1983'))),
                               'agv_nodes', 'agv1', visualization_interval=0)
        self.now = 0.0

    def send(self, name: str, **fields: Any) -> None:
        writer, reader = self.ports[name]
        self.now += 1.0  # apart by more than minStateInterval: each change is one state
        taken = reader.accept(writer.pack(fields), round(self.now * 1e9))
        assert taken is not None, reader.last_error
        self.core.on_record(name, taken, self.now)

    def state(self) -> dict[str, Any]:
        doc = json.loads(to_json(self.core.state()))
        errors = [e.message for e in validator_for(SCHEMA)(SCHEMA).iter_errors(doc)]
        assert not errors, errors
        return doc


@pytest.fixture
def records() -> Records:
    return Records()


def test_a_card_is_read_once_however_many_heartbeats_repeat_it(records):
    # position_sensor_status: `recognitions` counts recognitions; heartbeats repeat the last
    records.send('position_sensor_status', recognised=0, identity=0xFF, recognitions=0)
    assert records.state()['lastNodeId'] == ''
    records.send('position_sensor_status', recognised=1, identity=0, recognitions=1)
    assert records.state()['lastNodeId'] == 'L0'  # identity 0: location marker L0 (UCTAB)
    for _ in range(3):
        records.send('position_sensor_status', recognised=0, identity=0, recognitions=1)
    assert records.core.records.reads == 1


def test_a_recognition_in_the_positioning_table_is_no_card_read(records):
    records.send('position_sensor_status', recognitions=0)
    records.send('position_sensor_status', recognised=1, table='positioning', identity=0xFF,
                 stop_view=4, recognitions=1)
    assert records.core.records.reads == 0 and records.state()['lastNodeId'] == ''


def test_the_conveyors_load_sensors_are_the_loads(records):
    assert 'loads' not in records.state()  # load handling not heard: the truck cannot tell
    records.send('load_status', load_first=0, load_second=0)
    assert records.state()['loads'] == []
    records.send('load_status', load_first=0, load_second=1)
    assert records.state()['loads'] == [{'loadPosition': 'second'}]
    records.send('load_status', load_first=1, load_second=1)
    assert records.state()['loads'] == [{'loadPosition': 'first'}, {'loadPosition': 'second'}]


def test_traction_radio_stop_bumper_and_manual(records):
    records.send('traction_status', emergency_stop=1)  # the executive's commanded stop
    state = records.state()
    assert state['safetyState'] == {'eStop': 'NONE', 'fieldViolation': False}
    assert state['operatingMode'] == 'AUTOMATIC'
    records.send('traction_status', radio_stop=1)
    assert records.state()['safetyState'] == {'eStop': 'REMOTE', 'fieldViolation': False}
    records.send('traction_status', bumper=1)
    assert records.state()['safetyState'] == {'eStop': 'NONE', 'fieldViolation': True}
    records.send('traction_status', manual=1)
    assert records.state()['operatingMode'] == 'MANUAL'


def test_a_record_the_bridge_does_not_read_is_refused_by_name(records):
    with pytest.raises(ValueError, match='comms_status'):
        records.core.on_record('comms_status', {}, 0.0)
