"""The vda5050_bridge node on a secured mosquitto: TLS, a client certificate, a password file.

The bridge runs as its own process (the console script, as agv-launch starts it) with the TLS
and credential parameters of agv_nodes/vda5050/parameters.yaml; mosquitto (test/mqtt_broker.py)
decides whether it may connect. A master's link with its own credentials sees the bridge's
connection message go ONLINE. Bad security parameters stop the node at start-up with one line
naming the parameter and its value; the password itself never appears in argv or the output.
"""

from __future__ import annotations

from collections.abc import Iterator
import json
from pathlib import Path
import queue
import subprocess
import time

from mqtt_broker import TestCa, require_mosquitto
import pytest

from agv_nodes.mqtt.address import ENV_PASSWORD, LinkSecurity
from agv_nodes.mqtt.client import MqttLink
from agv_nodes.mqtt.mosquitto import Mosquitto

from conftest import PYTHON

pytestmark = [pytest.mark.dds]
BRIDGE = str(Path(PYTHON).parent / 'vda5050_bridge')
PASSWORD = 'truck-secret-7'
CONNECTION = 'uagv/v2/agv_nodes/agv1/connection'


@pytest.fixture(scope='module')
def secured(tmp_path_factory) -> Iterator[tuple[Mosquitto, TestCa, Path]]:
    """Mosquitto with TLS, client certificates required, users agv1 and master."""
    require_mosquitto()
    directory = tmp_path_factory.mktemp('secured')
    ca = TestCa(directory / 'ca')
    with Mosquitto(tls=ca.broker_tls(require_certificate=True),
                   passwords={'agv1': PASSWORD, 'master': 'master-secret'}) as broker:
        yield broker, ca, directory


def _bridge_args(url: str, **parameters: str) -> list[str]:
    args = [BRIDGE, '--ros-args', '-p', f'mqtt_url:={url}', '-p', 'serial_number:=agv1']
    for name, value in parameters.items():
        args += ['-p', f'{name}:={value}']
    return args


@pytest.mark.timeout(90)
def test_the_bridge_comes_online_on_a_tls_broker_with_its_password_from_a_file(secured):
    """TLS files and password_file as parameters: the master hears ONLINE over mqtts://."""
    broker, ca, directory = secured
    truck, master = ca.issue('agv1', server=False), ca.issue('master', server=False)
    password_file = directory / 'agv1.password'
    password_file.write_text(PASSWORD + '\n')
    password_file.chmod(0o600)
    heard: queue.Queue[dict] = queue.Queue()
    watcher = MqttLink(broker.url, 'master', security=LinkSecurity(
        ca_file=str(ca.ca_file), cert_file=str(master.cert), key_file=str(master.key),
        username='master', password='master-secret'))
    watcher.connect(timeout=10.0)
    assert watcher.subscribe(CONNECTION, 1, lambda t, p: heard.put(json.loads(p)))
    args = _bridge_args(broker.url, tls_ca=str(ca.ca_file), tls_cert=str(truck.cert),
                        tls_key=str(truck.key), username='agv1',
                        password_file=str(password_file))
    bridge = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True)
    try:
        state = None
        while state != 'ONLINE':  # a retained CONNECTIONBROKEN of an earlier bridge may come
            try:
                state = heard.get(timeout=60.0)['connectionState']
            except queue.Empty:
                raise AssertionError('the bridge did not come ONLINE within 60 s') from None
    finally:
        bridge.terminate()
        output = bridge.communicate(timeout=20)[0]
        watcher.close()
    assert PASSWORD not in ' '.join(args) and PASSWORD not in output
    assert 'mqtts://127.0.0.1:' in output  # the bridge names its broker, without credentials


@pytest.mark.timeout(60)
@pytest.mark.parametrize(('parameters', 'environment', 'words'), [
    ({'tls_ca': '{ca}'}, {}, "parameter 'tls_ca' = '{ca}': TLS files apply to mqtts:// only"),
    ({'tls_ca': '/nonexistent/ca.pem'}, {},
     "parameter 'tls_ca' = '/nonexistent/ca.pem': no such file"),
    ({'tls_cert': '{ca}'}, {}, "parameter 'tls_key' = '': a client certificate needs its key"),
    ({'tls_ca': '{password}'}, {}, "parameter 'tls_ca' = '{password}': not a PEM CA"),
    ({'tls_cert': '{ca}', 'tls_key': '{ca}'}, {},
     "parameter 'tls_cert' = '{ca}': not a PEM certificate whose key is tls_key"),
    ({'username': 'agv1', 'password_file': '/nonexistent/pw'}, {},
     "parameter 'password_file' = '/nonexistent/pw': password file /nonexistent/pw: cannot "
     'read it'),
    ({}, {ENV_PASSWORD: PASSWORD},
     f"parameter 'username' = '': a password is given ({ENV_PASSWORD}) but no user name"),
], ids=['tls file with mqtt://', 'missing ca', 'cert without key', 'ca not PEM',
        'key not PEM', 'missing password file', 'password without user'])
def test_bad_security_parameters_stop_the_bridge_with_one_line(secured, monkeypatch,
                                                               parameters, environment, words):
    """Each: exit status 2, one line on stderr naming the parameter, value and what is wrong."""
    broker, ca, directory = secured
    for name, value in environment.items():
        monkeypatch.setenv(name, value)
    plain = parameters.get('tls_ca') == '{ca}'  # the one case given a plain mqtt:// URL
    url = broker.url.replace('mqtts://', 'mqtt://') if plain else broker.url
    text_file = directory / 'a.password'
    text_file.write_text('just a password\n')
    files = {'ca': ca.ca_file, 'password': text_file}
    given = {name: value.format(**files) for name, value in parameters.items()}
    run = subprocess.run(_bridge_args(url, **given), capture_output=True, text=True, timeout=50)
    assert run.returncode == 2, run.stdout + run.stderr
    (line,) = run.stderr.strip().splitlines()
    assert line.startswith('vda5050_bridge: ') and words.format(**files) in line, line
    assert PASSWORD not in run.stdout + run.stderr


DISPATCHER = str(Path(PYTHON).parent / 'dispatcher')


@pytest.mark.timeout(90)
def test_the_dispatcher_connects_to_a_tls_broker_with_the_same_parameters(secured):
    """The fleet's master takes the same five parameters; mosquitto's log shows it accepted."""
    broker, ca, directory = secured
    pair = ca.issue('dispatcher', server=False)
    password_file = directory / 'master.password'
    password_file.write_text('master-secret\n')
    args = [DISPATCHER, '--ros-args', '-p', f'mqtt_url:={broker.url}', '-p', 'trucks:=[agv1]',
            '-p', f'tls_ca:={ca.ca_file}', '-p', f'tls_cert:={pair.cert}',
            '-p', f'tls_key:={pair.key}', '-p', 'username:=master',
            '-p', f'password_file:={password_file}']
    dispatcher = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True)
    accepted = "as agv_nodes_dispatcher (p2, c1, k30, u'master')"
    try:
        deadline = time.monotonic() + 60.0
        while accepted not in broker.log_path.read_text():
            assert dispatcher.poll() is None, dispatcher.communicate(timeout=10)[0][-2000:]
            assert time.monotonic() < deadline, 'mosquitto did not accept the dispatcher'
            time.sleep(0.1)
    finally:
        dispatcher.terminate()
        dispatcher.communicate(timeout=20)


@pytest.mark.timeout(60)
def test_a_bad_security_parameter_stops_the_dispatcher_with_one_line(secured):
    """TLS files for a plain URL: exit status 2 and one line naming the parameter."""
    broker, ca, _ = secured
    url = broker.url.replace('mqtts://', 'mqtt://')
    run = subprocess.run([DISPATCHER, '--ros-args', '-p', f'mqtt_url:={url}', '-p',
                          'trucks:=[agv1]', '-p', f'tls_ca:={ca.ca_file}'],
                         capture_output=True, text=True, timeout=50)
    assert run.returncode == 2, run.stdout + run.stderr
    (line,) = run.stderr.strip().splitlines()
    assert line.startswith(f"dispatcher: parameter 'tls_ca' = '{ca.ca_file}': TLS files "
                           'apply to mqtts:// only'), line
