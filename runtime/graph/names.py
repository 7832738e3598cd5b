"""What a graph may name: graph and process names, zenoh key prefixes and endpoints.

Checked when the graph is read (and for ``--prefix``, ``--listen``, ``--connect``), so that
``umbra check`` refuses at its line what zenoh would refuse, or misroute, only when a run starts.
"""

from __future__ import annotations

import ipaddress
import re

from umbra.connectors.access.hosts import MAX_TCP_PORT, port_problem
from umbra.connectors.access.secret import is_loopback

#: Longest graph, process or module name [characters].
MAX_NAME_CHARS = 64
#: Longest zenoh key prefix [characters].
MAX_PREFIX_CHARS = 200
_CHUNK_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")
#: zenoh link protocols whose address is ``HOST:PORT``.
IP_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
#: Other zenoh link protocols (a path or a device after the slash).
OTHER_PROTOCOLS = ("unixsock-stream", "unixpipe", "serial", "vsock")
_HOST_RE = re.compile(r"^[A-Za-z0-9]([A-Za-z0-9\-]{0,62})(\.[A-Za-z0-9]([A-Za-z0-9\-]{0,62}))*$")


def key_prefix_problem(prefix: str) -> str:
    """Why ``prefix`` cannot start the zenoh keys of a graph's links; empty when it can.
    Chunks are separated by ``/`` and hold letters, digits, ``_ . -`` only: no wildcard
    (``*``, ``**``, ``$*``), no ``?`` or ``#``, no empty chunk, no leading or trailing ``/``."""
    if not prefix:
        return "the key prefix is empty"
    if len(prefix) > MAX_PREFIX_CHARS:
        return f"the key prefix has {len(prefix)} characters, at most {MAX_PREFIX_CHARS}"
    for chunk in prefix.split("/"):
        if not chunk:
            return f"key prefix `{prefix}` has an empty chunk (a leading, trailing or double `/`)"
        if not _CHUNK_RE.match(chunk):
            return (
                f"key prefix `{prefix}`: chunk `{chunk}` may hold only letters, digits, `_`, `.` "
                "and `-` (zenoh wildcards `*`, `$`, `?`, `#` would match other graphs' keys)"
            )
    return ""


def endpoint_problem(endpoint: str) -> str:
    """Why ``endpoint`` is not a zenoh locator like ``tcp/127.0.0.1:7447``; empty when it is."""
    if not isinstance(endpoint, str) or "/" not in endpoint:
        return f"expected a zenoh endpoint like `tcp/127.0.0.1:7447`, found {endpoint!r}"
    protocol, _, rest = endpoint.partition("/")
    address = re.split(r"[?#]", rest, maxsplit=1)[0]
    if protocol in OTHER_PROTOCOLS:
        return "" if address else f"endpoint `{endpoint}` names no address after `{protocol}/`"
    if protocol not in IP_PROTOCOLS:
        known = ", ".join(IP_PROTOCOLS + OTHER_PROTOCOLS)
        return f"endpoint `{endpoint}`: unknown protocol `{protocol}` (one of {known})"
    host, sep, port = address.rpartition(":")
    if not sep or not host:
        return f"endpoint `{endpoint}` needs HOST:PORT after `{protocol}/`"
    if not port.isdigit() or port_problem(int(port)):
        return (
            f"endpoint `{endpoint}`: port must be a number from 0 to {MAX_TCP_PORT}, found `{port}`"
        )
    if host.startswith("[") and host.endswith("]"):
        host_ok = _is_ip(host[1:-1], 6)
    else:
        host_ok = _is_ip(host, 4) or bool(_HOST_RE.match(host))
    if not host_ok:
        return f"endpoint `{endpoint}`: `{host}` is not an IP address or a host name"
    return ""


#: Protocols whose links are encrypted and authenticated by certificates.
TLS_PROTOCOLS = ("tls", "quic")
#: Protocols whose links never leave this host (a Unix socket or pipe: a path, not an address).
HOST_PROTOCOLS = ("unixsock-stream", "unixpipe")


def endpoint_host(endpoint: str) -> tuple[str, str]:
    """``(protocol, host)`` of a zenoh endpoint ``proto/host:port[?...][#...]``."""
    protocol, _, rest = endpoint.partition("/")
    address = rest.split("#", 1)[0].split("?", 1)[0]
    if address.startswith("["):  # [v6]:port
        return protocol, address[1 : address.find("]")]
    return protocol, address.rsplit(":", 1)[0]


def plain_beyond_host(endpoint: str) -> bool:
    """Whether ``endpoint`` is reachable from beyond this host without TLS (plain TCP, UDP,
    websockets... on an address that is not loopback: ``0.0.0.0`` and host names included)."""
    protocol, host = endpoint_host(endpoint)
    return not (protocol in TLS_PROTOCOLS or protocol in HOST_PROTOCOLS or is_loopback(host))


def _is_ip(text: str, version: int) -> bool:
    try:
        return ipaddress.ip_address(text).version == version
    except ValueError:
        return False
