"""A private mosquitto for each MQTT test module, and a test CA to give it TLS.

`mosquitto_url` (a module fixture, imported into a test module) starts mosquitto on a free
127.0.0.1 port with agv_nodes.mqtt.mosquitto and stops it after the module. mosquitto is what
plants run and what CI installs (./agv.sh test); a machine without it fails these tests with
one line saying how to install it, rather than skipping them. `TestCa` makes a CA, server and
client certificates with the `cryptography` package, into a directory of the test's own.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
import datetime
import ipaddress
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID
import pytest

from agv_nodes.mqtt.mosquitto import BrokerTls, Mosquitto, find_mosquitto

MISSING = ('mosquitto is not installed: ./agv.sh test installs it as root (apt-get), or '
           'install the Debian package mosquitto')


def require_mosquitto() -> str:
    """Return the executable; fail the test in one line when mosquitto is missing."""
    executable = find_mosquitto()
    if executable is None:
        pytest.fail(MISSING, pytrace=False)
    return executable


@pytest.fixture(scope='module')
def mosquitto_url() -> Iterator[str]:
    """mqtt://127.0.0.1:PORT of an anonymous mosquitto private to the test module."""
    require_mosquitto()
    with Mosquitto() as broker:
        yield broker.url


@dataclass(frozen=True)
class Pair:
    """A certificate and its key, as PEM files."""

    cert: Path
    key: Path


class TestCa:
    """A certificate authority for one test: it signs a broker's and clients' certificates."""

    __test__ = False  # a helper, not a test class

    def __init__(self, directory: Path, name: str = 'agv test CA') -> None:
        self.directory = directory
        directory.mkdir(parents=True, exist_ok=True)
        self._key = ec.generate_private_key(ec.SECP256R1())
        self._name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
        now = datetime.datetime.now(datetime.UTC)
        self._cert = (
            x509.CertificateBuilder().subject_name(self._name).issuer_name(self._name)
            .public_key(self._key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(days=1))
            .not_valid_after(now + datetime.timedelta(days=30))
            .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
            .add_extension(x509.KeyUsage(
                digital_signature=True, content_commitment=False, key_encipherment=False,
                data_encipherment=False, key_agreement=False, key_cert_sign=True,
                crl_sign=True, encipher_only=False, decipher_only=False), critical=True)
            .sign(self._key, hashes.SHA256()))
        self.ca_file = directory / f'{name.replace(" ", "_")}.pem'
        self.ca_file.write_bytes(self._cert.public_bytes(serialization.Encoding.PEM))

    def issue(self, common_name: str, server: bool) -> Pair:
        """Sign a certificate: a server's for 127.0.0.1 and localhost, or a client's."""
        key = ec.generate_private_key(ec.SECP256R1())
        now = datetime.datetime.now(datetime.UTC)
        usage = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
        builder = (
            x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)]))
            .issuer_name(self._name).public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(days=1))
            .not_valid_after(now + datetime.timedelta(days=30))
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(x509.ExtendedKeyUsage([usage]), critical=False))
        if server:
            builder = builder.add_extension(x509.SubjectAlternativeName([
                x509.IPAddress(ipaddress.ip_address('127.0.0.1')), x509.DNSName('localhost')]),
                critical=False)
        cert = builder.sign(self._key, hashes.SHA256())
        pair = Pair(self.directory / f'{common_name}.crt', self.directory / f'{common_name}.key')
        pair.cert.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        pair.key.write_bytes(key.private_bytes(serialization.Encoding.PEM,
                                               serialization.PrivateFormat.PKCS8,
                                               serialization.NoEncryption()))
        pair.key.chmod(0o600)
        return pair

    def broker_tls(self, require_certificate: bool) -> BrokerTls:
        """Return the broker's TLS: its certificate from this CA, clients checked against it."""
        server = self.issue('broker', server=True)
        return BrokerTls(self.ca_file, server.cert, server.key, require_certificate)
