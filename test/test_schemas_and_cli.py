"""Schema loading errors, the agv-records CLI, and the generated record tables."""

from __future__ import annotations

from pathlib import Path
import shutil
import subprocess

import pytest

from agv_nodes.package_share import schema_dir
from agv_nodes.records import SchemaError, codec, load_codec
from agv_nodes.records.cli import main as records_main
from agv_nodes.records.tables import render_markdown

from conftest import PYTHON, REPO

GOOD = """\
record: {name}
data_id: 0x70
kind: inter_processor
topic: test/topic
writer: a
readers: [b]
period_ms: 50
thesis: test
fields:
  - name: level
    byte: 1
    encoding: unsigned
    default: 0
    thesis: test
"""


def write_schema(tmp_path: Path, text: str, name: str = 'probe') -> Path:
    path = tmp_path / f'{name}.yaml'
    path.write_text(text.replace('{name}', name))
    return path


def test_good_probe_schema_loads(tmp_path):
    write_schema(tmp_path, GOOD)
    assert load_codec(tmp_path)['probe'].encode({'level': 3}, integrity='none')[0] == 3


@pytest.mark.parametrize('edit, key, value', [
    (('kind: inter_processor', 'kind: magic'), "'kind'", "'magic'"),
    (('data_id: 0x70', 'data_id: 300'), "'data_id'", '300'),
    (('topic: test/topic', 'topic: /abs/topic'), "'topic'", "'/abs/topic'"),
    (('    byte: 1\n', '    byte: 15\n'), "'byte'", '15'),
    (('    encoding: unsigned', '    encoding: bcd'), "'encoding'", "'bcd'"),
    (('    default: 0\n', '    default: 300\n'), "'default'", '300'),
    (('    byte: 1\n', '    byte: 1\n    bits: 9\n'), "'bits'", '9'),
    (('period_ms: 50', 'period_ms: -1'), "'period_ms'", '-1'),
    (('    thesis: test\n', '    thesis: test\n    colour: red\n'), "'colour'", ''),
])
def test_bad_schema_names_file_key_value(tmp_path, edit, key, value):
    path = write_schema(tmp_path, GOOD.replace(*edit))
    with pytest.raises(SchemaError) as info:
        load_codec(tmp_path)
    text = str(info.value)
    assert str(path) in text and key in text and value in text


def test_overlapping_fields_and_duplicates_rejected(tmp_path):
    text = GOOD + """\
  - name: flag
    byte: 1
    bits: 0
    encoding: flag
    zero: a
    one: b
    default: 0
    thesis: test
"""
    write_schema(tmp_path, text)
    with pytest.raises(SchemaError, match='overlaps'):
        load_codec(tmp_path)
    shutil.rmtree(tmp_path)
    tmp_path.mkdir()
    write_schema(tmp_path, GOOD, 'one')
    write_schema(tmp_path, GOOD.replace('test/topic', 'other'), 'two')
    with pytest.raises(SchemaError, match="'data_id'"):
        load_codec(tmp_path)


def test_yaml_boolean_enum_name_rejected(tmp_path):
    text = GOOD.replace('    encoding: unsigned\n    default: 0',
                        '    encoding: enum\n    values: {off: 0, on: 1}\n    default: 0')
    write_schema(tmp_path, text)
    with pytest.raises(SchemaError, match='quote it'):
        load_codec(tmp_path)


def test_unreadable_yaml_is_one_line(tmp_path):
    write_schema(tmp_path, 'record: probe\nfields: [a: b: c]\n')
    with pytest.raises(SchemaError) as info:
        load_codec(tmp_path)
    assert '\n' not in str(info.value)


# -- CLI --------------------------------------------------------------------------------
def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([PYTHON, '-m', 'agv_nodes.records.cli', *args], capture_output=True,
                          text=True, timeout=60)


def test_cli_encode_decode_round_trip():
    enc = run_cli('encode', 'navigation_status', 'at_location=1', 'slow=1', 'lost=1',
                  'last_marker=02H', '--integrity', 'none')
    assert enc.returncode == 0, enc.stderr
    assert enc.stdout.strip() == '0B02' + '00' * 14
    dec = run_cli('decode', 'navigation_status', enc.stdout.strip(), '--integrity', 'none')
    assert dec.returncode == 0
    assert 'last_marker: 2' in dec.stdout and 'at the requested location' in dec.stdout
    e2e = run_cli('encode', 'traction_link', 'speed=20', '--counter', '9')
    assert e2e.stdout.strip()[:2] == '14' and e2e.stdout.strip()[28:30] == '09'
    assert len(e2e.stdout.strip()) == 32


@pytest.mark.parametrize('args, words', [
    (('decode', 'traction_command', '00' * 15), 'length 15'),
    (('decode', 'traction_command', 'zz'), 'not a hex string'),
    (('decode', 'navigation_status', '0AFF' + '00' * 14), 'bad CRC'),
    (('encode', 'traction_command', 'demand=99'), "field 'demand'"),
    (('encode', 'traction_command', 'demand'), 'expected field=value'),
    (('encode', 'route_command', 'mode=sideways'), 'unknown enum'),
    (('show', 'no_such_record'), 'no such record'),
    (('--schemas', '/nonexistent', 'list'), 'no record schemas'),
    (('frobnicate',), 'invalid choice'),
])
def test_cli_bad_input_exit_2_one_line(args, words):
    res = run_cli(*args)
    assert res.returncode == 2
    assert 'Traceback' not in res.stderr
    assert words in res.stderr
    assert len(res.stderr.strip().splitlines()) <= 2  # argparse adds its usage line


def test_cli_list_and_show(capsys):
    assert records_main(['list']) == 0
    out = capsys.readouterr().out
    assert len(out.strip().splitlines()) == len(codec().names())
    assert records_main(['show', 'traction_link']) == 0
    assert '| 1 | 6 | `executive_priority` | flag |' in capsys.readouterr().out


def test_console_script_installed():
    exe = Path(PYTHON).parent / 'agv-records'
    assert exe.exists(), 'pip install -e . must install the agv-records console script'
    res = subprocess.run([str(exe), 'list'], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and 'traction_link' in res.stdout


def test_docs_records_md_is_fresh():
    expected = render_markdown(codec())
    current = (REPO / 'docs' / 'records.md').read_text()
    assert current == expected, 'stale: run agv-records doc --output docs/records.md'


def test_schemas_found_from_source_checkout():
    assert schema_dir() == REPO / 'msg_schemas'
