"""agv-records echo: a live record topic printed field by field, with each record's verdict.

The expected values are what the writer was told to send (the field values on dds_peer's
command line, records packed from the byte tables and sealed with the CRC the docs give, as the
stand-in executive packs them), and the verdicts the documented rejection reasons of
docs/records.md.
"""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

import pytest
from standin_executive import crc8_sae_j1850  # written from docs/records.md alone
import yaml

from agv_nodes.records import codec
from agv_nodes.records.cli import main
from agv_nodes.records.echo import describe_record, find_schema
from agv_nodes.records.ports import RecordReader

HERE = Path(__file__).resolve().parent
SENT = {'manual': 0, 'manual_speed': 0, 'reverse': 0, 'demand': 37, 'executive_priority': 1}


def packed(counter: int, demand: int = 37) -> bytes:
    """traction_command from its byte table (docs/records.md), sealed as the docs say."""
    body = bytes([0, demand & 0xFF, 1] + [0] * 11 + [counter])
    return body + bytes([crc8_sae_j1850(bytes([0x21]) + body)])


def document(text: str) -> dict:
    return yaml.safe_load(text.removesuffix('---'))


@pytest.mark.timeout(30)
def test_each_record_is_printed_with_its_fields_and_the_readers_verdict():
    schema = find_schema(codec(), '/traction/command')
    assert schema.name == 'traction_command'
    reader = RecordReader(schema, 'e2e')
    first = document(describe_record(reader, packed(7), 0))
    assert first['verdict'].startswith('accepted')
    assert {k: first[k] for k in SENT} == SENT
    assert document(describe_record(reader, packed(8), 1))['verdict'].startswith('accepted')
    repeated = document(describe_record(reader, packed(8), 2))
    assert repeated['verdict'].startswith('rejected repeated_counter')
    assert repeated['demand'] == 37  # what the bytes say, though no node acts on them
    bad = bytearray(packed(9))
    bad[15] ^= 0x01
    assert document(describe_record(reader, bytes(bad), 3))['verdict'] == 'rejected bad_crc'


@pytest.mark.timeout(30)
def test_an_unknown_record_is_one_line_and_status_2(capsys):
    assert main(['echo', 'no_such_record']) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and "'no_such_record'" in err and 'agv-records list' in err


@pytest.mark.dds
@pytest.mark.timeout(90)
def test_echo_decodes_a_live_topic():
    env = dict(os.environ, PYTHONPATH=str(HERE))
    args = [f'{k}={v}' for k, v in SENT.items()]
    peer = subprocess.Popen([sys.executable, str(HERE / 'dds_peer.py'), 'pub',
                             'traction_command', *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        done = subprocess.run([sys.executable, '-m', 'agv_nodes.records.cli', 'echo',
                               'traction/command', '--count', '3', '--timeout', '30'],
                              env=env, capture_output=True, text=True, timeout=60)
    finally:
        peer.terminate()
        peer.wait(10)
    assert done.returncode == 0, done.stderr
    docs = [yaml.safe_load(d) for d in done.stdout.split('\n---') if d.strip()]
    assert len(docs) == 3
    counters = []
    for doc in docs:
        assert doc['record'] == 'traction_command'
        assert doc['verdict'].startswith('accepted')
        assert {k: doc[k] for k in SENT} == SENT
        assert len(doc['writer']) >= 32  # the writer's GID, hex
        counters.append(doc['e2e_counter'])
    assert counters == [(counters[0] + k) & 0xFF for k in range(3)]
