"""Certificates and per-process zenoh configurations for mutual TLS (``umbra keys``).

For a graph, ``write_keys`` makes a certificate authority and, for each process, a key and a
certificate whose common name names the process (``runtime.links.acl.common_name``), then a zenoh
configuration per process (``PROCESS.json5``): mutual TLS with that certificate, and the
access-control rules derived from the graph with the certificates' common names as subjects.
Nothing is written by hand.

The CA's private key is not kept: to add or replace a process, make the folder again (every
process then gets new certificates), so nobody can issue a certificate later from a copy of the
folder. Keys are EC P-256; each private key file is mode 0600. Certificate paths in the
configurations are relative to the folder (``runtime.links.config`` resolves them), so the folder
can be copied to each host as it is.

Each certificate names ``localhost`` and ``127.0.0.1`` and any ``--host`` addresses given for its
process. Zenoh's check of the listener's name on connect is off (``verify_name_on_connect``):
both ends prove who they are with a certificate of this CA, and the rules key on its common name.
"""

from __future__ import annotations

import datetime
import ipaddress
import json
import os
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from runtime.graph.plan import GraphPlan
from runtime.links.acl import by_certificate, common_name, zenoh_acl

CA_FILE = "ca.pem"
#: Zenoh TLS settings that name files (resolved relative to the configuration's folder).
TLS_FILE_KEYS = (
    "root_ca_certificate",
    "listen_private_key",
    "listen_certificate",
    "connect_private_key",
    "connect_certificate",
)


def _name(cn: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "umbra"),
            x509.NameAttribute(NameOID.COMMON_NAME, cn),
        ]
    )


def _alt_names(hosts: list[str]) -> list[x509.GeneralName]:
    names: list[x509.GeneralName] = []
    for host in ["localhost", "127.0.0.1", *hosts]:
        try:
            names.append(x509.IPAddress(ipaddress.ip_address(host)))
        except ValueError:
            names.append(x509.DNSName(host))
    return names


def _pem_key(key: ec.EllipticCurvePrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _write(path: Path, data: bytes, mode: int) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, mode)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.chmod(path, mode)


def write_keys(
    plan: GraphPlan, out: Path, days: int = 365, hosts: dict[str, list[str]] | None = None
) -> list[Path]:
    """Write the CA certificate, a key and certificate per process and ``PROCESS.json5`` per
    process of ``plan`` into ``out``; the files written."""
    hosts = hosts or {}
    out.mkdir(parents=True, exist_ok=True)
    os.chmod(out, 0o700)  # it holds private keys
    graph = plan.spec.name
    now = datetime.datetime.now(datetime.timezone.utc)
    start, end = now - datetime.timedelta(minutes=5), now + datetime.timedelta(days=days)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = _name(f"umbra CA of graph {graph}")
    ca = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=False,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .sign(ca_key, hashes.SHA256())
    )
    written = [out / CA_FILE]
    _write(out / CA_FILE, ca.public_bytes(serialization.Encoding.PEM), 0o644)
    acl = zenoh_acl(plan, by_certificate(graph))
    for process in plan.populated_processes:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (
            x509.CertificateBuilder()
            .subject_name(_name(common_name(graph, process)))
            .issuer_name(ca_name)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(start)
            .not_valid_after(end)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .add_extension(
                x509.ExtendedKeyUsage(
                    [ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]
                ),
                critical=False,
            )
            .add_extension(
                x509.SubjectAlternativeName(_alt_names(hosts.get(process, []))), critical=False
            )
            .sign(ca_key, hashes.SHA256())
        )
        key_file, cert_file = out / f"{process}.key", out / f"{process}.pem"
        _write(key_file, _pem_key(key), 0o600)
        _write(cert_file, cert.public_bytes(serialization.Encoding.PEM), 0o644)
        config = {
            "transport": {
                "link": {
                    "tls": {
                        "root_ca_certificate": CA_FILE,
                        "listen_private_key": key_file.name,
                        "listen_certificate": cert_file.name,
                        "connect_private_key": key_file.name,
                        "connect_certificate": cert_file.name,
                        "enable_mtls": True,
                        "verify_name_on_connect": False,
                    }
                }
            },
            "access_control": acl,
        }
        header = (
            f"// zenoh configuration of process `{process}` of graph `{graph}`, written by "
            f"`umbra keys`:\n// mutual TLS with certificate CN={common_name(graph, process)} "
            f"and the graph's access rules.\n// Use: umbra run GRAPH --process {process} "
            f"--zenoh-config {out.name}/ --listen tls/HOST:PORT (or --connect)\n"
        )
        config_file = out / f"{process}.json5"
        _write(config_file, (header + json.dumps(config, indent=2) + "\n").encode(), 0o600)
        written += [key_file, cert_file, config_file]
    return written
