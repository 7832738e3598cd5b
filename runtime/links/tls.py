"""Certificates and per-process zenoh configurations for mutual TLS (``umbra keys``).

For a graph, ``write_keys`` makes a certificate authority and, for each process, a key and a
certificate whose common name names the process (``umbra.runtime.links.acl.common_name``), then a
zenoh configuration per process (``PROCESS.json5``): mutual TLS with that certificate, and the
access-control rules derived from the graph with the certificates' common names as subjects.
Nothing is written by hand.

The CA's private key is not kept: to add or replace a process, make the folder again (every
process then gets new certificates), so nobody can issue a certificate later from a copy of the
folder. Keys are EC P-256; each private key file is mode 0600. Certificate paths in the
configurations are relative to the folder (``umbra.runtime.links.config`` resolves them), so the
folder can be copied to each host as it is.

``ros2@NAME.json5`` (``--ros2 NAME``) is mutual TLS with a certificate of the same CA and no
access rules: the configuration of a ROS 2 router endpoint's ends (``umbra run --ros2-config``,
the router, ROS 2 hosts). Its common name is no process's, so the graph's rules give it nothing
on the links.

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

from umbra.runtime.graph.plan import GraphPlan
from umbra.runtime.links.acl import (
    Observer,
    by_certificate,
    common_name,
    observer_certificate_name,
    ros2_certificate_name,
    zenoh_acl,
)

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


def observer_file(name: str) -> str:
    """Stem of the files of observer ``name`` (``@`` is in no process name: no clash)."""
    return f"observer@{name}"


def ros2_file(name: str) -> str:
    """Stem of the files of ROS 2 certificate ``name`` (``@`` is in no process name)."""
    return f"ros2@{name}"


def write_keys(
    plan: GraphPlan,
    out: Path,
    days: int = 365,
    hosts: dict[str, list[str]] | None = None,
    observers: dict[str, list[str]] | None = None,
    ros2: list[str] | None = None,
) -> list[Path]:
    """Write the CA certificate, a key and certificate per process and ``PROCESS.json5`` per
    process of ``plan`` into ``out``, and for each of ``observers`` (name -> the keys it may
    read) a key, a certificate, ``observer@NAME.json5`` and ``observer@NAME.keys.json`` (the
    prefix and keys, for ``umbra topics``), and for each of ``ros2`` a key, a certificate and
    ``ros2@NAME.json5`` (TLS only, for a ROS 2 router endpoint); the files written."""
    hosts = hosts or {}
    observers = observers or {}
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
    readers = [
        Observer(name, {"cert_common_names": [observer_certificate_name(graph, name)]}, tuple(k))
        for name, k in observers.items()
    ]
    acl = zenoh_acl(plan, by_certificate(graph), readers)
    names: list[tuple[str, str, list[str], Observer | None]] = [
        (p, common_name(graph, p), hosts.get(p, []), None) for p in plan.populated_processes
    ]
    names += [(observer_file(o.name), o.subject["cert_common_names"][0], [], o) for o in readers]
    names += [(ros2_file(n), ros2_certificate_name(graph, n), [], None) for n in ros2 or []]
    for process, cn, alt, observer in names:
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (
            x509.CertificateBuilder()
            .subject_name(_name(cn))
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
            .add_extension(x509.SubjectAlternativeName(_alt_names(alt)), critical=False)
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
            f"`umbra keys`:\n// mutual TLS with certificate CN={cn} "
            f"and the graph's access rules.\n// Use: umbra run GRAPH --process {process} "
            f"--zenoh-config {out.name}/ --listen tls/HOST:PORT (or --connect)\n"
        )
        if process.startswith(ros2_file("")):
            del config["access_control"]  # ROS 2 keys are no graph's: TLS only
            header = (
                f"// zenoh configuration of ROS 2 end `{process.removeprefix(ros2_file(''))}` "
                f"of graph `{graph}`, written by `umbra keys`:\n// mutual TLS with certificate "
                f"CN={cn}, no access rules (the graph's give it nothing on the links).\n"
                f"// Use: umbra run GRAPH --ros2-router tls/HOST:PORT --ros2-config "
                f"{out.name}/{process}.json5\n// (or in a ROS 2 router's or host's zenoh "
                "configuration, with its own mode and endpoints)\n"
            )
        if observer is not None:
            del config["access_control"]  # the processes' rules hold it to its keys
            header = (
                f"// zenoh configuration of observer `{observer.name}` of graph `{graph}`, "
                f"written by `umbra keys`:\n// mutual TLS with certificate CN={cn}; the "
                f"graph's processes let it read {len(observer.keys)} keys and nothing else.\n"
                f"// Use: umbra topics --zenoh-config {out.name}/{process}.json5 "
                f"--connect tls/HOST:PORT\n"
            )
            keys_file = out / f"{process}.keys.json"
            keys = {"prefix": plan.key_prefix, "keys": list(observer.keys)}
            _write(keys_file, (json.dumps(keys, indent=2) + "\n").encode(), 0o644)
            written.append(keys_file)
        config_file = out / f"{process}.json5"
        _write(config_file, (header + json.dumps(config, indent=2) + "\n").encode(), 0o600)
        written += [key_file, cert_file, config_file]
    return written
