"""The names a page server answers to, and the origin of its own pages (pure).

A browser sends the name it looked up in ``Host``; a DNS-rebinding page (``attacker.example``
resolving to 127.0.0.1) sends its own name there, and its own origin in ``Origin``. So the server
answers only to the names it was started for: ``127.0.0.1:PORT``, ``localhost:PORT``,
``[::1]:PORT``, and, when it listens beyond loopback, the address it is bound to (or, bound to
every interface, this machine's host names).
"""

from __future__ import annotations

import socket
from urllib.parse import urlsplit

from umbra.connectors.access.secret import is_loopback

WILDCARDS = ("0.0.0.0", "::", "")
#: Highest TCP port number; 0 asks the system for a free one.
MAX_TCP_PORT = 65535


def port_problem(port: int) -> str:
    """Why ``port`` cannot be a TCP port to listen on ("" when it can)."""
    if 0 <= port <= MAX_TCP_PORT:
        return ""
    return f"expected a port from 0 to {MAX_TCP_PORT} (0: any free one), found {port}"


def origin_problem(origin: str) -> str:
    """Why ``origin`` is not a page origin ``scheme://host[:port]`` ("" when it is)."""
    parts = urlsplit(origin.strip())
    try:
        numeric_port = parts.port is None or parts.port >= 0  # raises on a port not a number
    except ValueError:
        numeric_port = False
    page = parts.scheme in ("http", "https") and bool(parts.hostname) and parts.path in ("", "/")
    if page and numeric_port:
        return ""
    return (
        "expected a page origin http(s)://host[:port], e.g. http://127.0.0.1:8080, "
        f"found {origin!r}"
    )


def _netloc(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def allowed_hosts(bound: str, port: int) -> frozenset[str]:
    """Every ``Host`` value (lower case, with the port) a server bound to ``bound``:``port``
    answers to."""
    names = {_netloc(h, port) for h in ("127.0.0.1", "localhost", "::1")}
    if bound in WILDCARDS:
        for name in {socket.gethostname(), socket.getfqdn()}:
            if name:
                names.add(_netloc(name, port))
    elif not is_loopback(bound):
        names.add(_netloc(bound, port))
    return frozenset(n.lower() for n in names)


def host_allowed(host: str | None, allowed: frozenset[str]) -> bool:
    """Whether a request's ``Host`` header names this server."""
    return host is not None and host.strip().lower() in allowed


def origin_allowed(origin: str | None, allowed: frozenset[str]) -> bool:
    """Whether an ``Origin`` header (None: absent) is one of this server's own pages. Absent is
    allowed here (clients that are not browsers send none; the gate asks POSTs for more);
    ``null`` and every other site are not."""
    if origin is None:
        return True
    try:
        parts = urlsplit(origin.strip())
    except ValueError:
        return False
    return parts.scheme in ("http", "https") and parts.netloc.lower() in allowed
