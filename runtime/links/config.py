"""Zenoh configuration for links: safe defaults, explicit endpoints, an optional user file.

Every configuration built here:

* runs in peer mode unless a user file names another mode (client, router);
* turns multicast and gossip scouting off — always, whatever a user file says — because zenoh's
  stock default multicasts out of the machine's network interface;
* lists its listen and connect endpoints explicitly (zenoh's own default listens on every
  interface): on one host the defaults are loopback ``tcp/127.0.0.1:PORT`` endpoints;
* retries connect endpoints quickly (a peer that comes back, or a link that returns, is rejoined
  without restarting anything) and uses a short lease, so a silent peer's link is dropped within
  about a second (``LEASE_MS``): a peer on another host is then gone, one on this host whose
  process lives is late until it returns or dies (``umbra.runtime.links.late``);
* keeps zenoh's shared-memory transport on, so large samples between processes on one host travel
  as shared-memory references (see ``umbra.runtime.links.shm``).
"""

from __future__ import annotations

import json
import re
import socket
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from umbra.connectors.errors import UserError
from umbra.connectors.user_files import read_text
from umbra.runtime.links.auth import apply_auth

#: Lease of a zenoh link [ms]: a peer that sends nothing for this long loses its link and its
#: token (gone, or late while its process on this host lives: ``umbra.runtime.links.late``).
LEASE_MS = 1000
#: Longest a connecting peer may take over zenoh's handshake [ms] (zenoh's default: 10 s). A
#: handshake over loopback or a LAN takes milliseconds, with TLS tens; a peer that opens a
#: connection and says nothing (or junk) holds a slot, and the session's close waits for it, no
#: longer than this.
ACCEPT_TIMEOUT_MS = 2000
#: Handshakes under way at once (zenoh's default: 100): what half-open connections can hold.
ACCEPT_PENDING = 16
#: Keep-alive messages per lease period.
KEEP_ALIVE = 4
#: First base port of the default loopback mesh of ``umbra run GRAPH --process NAME``.
DEFAULT_BASE_PORT = 7447
LOOPBACK = "127.0.0.1"
_ENDPOINT_RE = re.compile(r"^[a-z][a-z0-9+-]*/\S+$")


@dataclass
class Endpoints:
    """Where one process listens and what it connects to (zenoh locators, ``tcp/HOST:PORT``)."""

    listen: list[str] = field(default_factory=list)
    connect: list[str] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.listen and not self.connect


def check_endpoint(text: str, where: str) -> str:
    """``text`` when it looks like a zenoh endpoint (``tcp/127.0.0.1:7447``); UserError if not."""
    if not isinstance(text, str) or not _ENDPOINT_RE.match(text.strip()):
        raise UserError(
            f"{where}: expected a zenoh endpoint like `tcp/127.0.0.1:7447`, found {text!r}"
        )
    return text.strip()


def loopback_mesh(
    processes: list[str], ports: list[int], protocol: str = "tcp"
) -> dict[str, Endpoints]:
    """Loopback endpoints joining every pair of ``processes``: process i listens on
    ``PROTOCOL/127.0.0.1:ports[i]`` and connects to every process before it (peers do not route
    for each other, so a graph of three processes needs all three pairs)."""
    if len(ports) < len(processes):
        raise ValueError(f"need {len(processes)} ports, got {len(ports)}")
    mesh = {}
    for i, name in enumerate(processes):
        mesh[name] = Endpoints(
            listen=[f"{protocol}/{LOOPBACK}:{ports[i]}"],
            connect=[f"{protocol}/{LOOPBACK}:{ports[j]}" for j in range(i)],
        )
    return mesh


def default_mesh(processes: list[str], base_port: int = DEFAULT_BASE_PORT) -> dict[str, Endpoints]:
    """The fixed loopback mesh used by ``--process NAME`` without endpoints: process i of the graph
    listens on ``base_port + i``, so processes started by hand on one host find each other."""
    return loopback_mesh(processes, [base_port + i for i in range(len(processes))])


def free_loopback_ports(count: int) -> list[int]:
    """``count`` distinct TCP ports free on 127.0.0.1 right now (the OS picks them)."""
    sockets = []
    try:
        for _ in range(count):
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.bind((LOOPBACK, 0))
            sockets.append(s)
        return [s.getsockname()[1] for s in sockets]
    finally:
        for s in sockets:
            s.close()


def _json(value: object) -> str:
    return json.dumps(value)


#: Largest zenoh configuration file read [bytes].
MAX_CONFIG_BYTES = 1_000_000
_PARSER_AT = re.compile(r"-->\s*(\d+):(\d+)")
_PARSER_WHY = re.compile(r"^\s*=\s*(.*?)(?: at /\S+)?\.?\s*$", re.MULTILINE)


def read_user_config(path: str) -> zenoh.Config:
    """Parse the user's zenoh configuration file ``path`` (bounded in size; UserError
    ``FILE:LINE:COL: error:`` when zenoh refuses it), its TLS file names made absolute."""
    file = Path(path)
    read_text(file, "zenoh configuration file (JSON5)", MAX_CONFIG_BYTES)  # a bounded file
    try:
        cfg: zenoh.Config = zenoh.Config.from_file(str(file))
    except Exception as exc:  # zenoh raises ZError with its parser's message
        raise UserError(_parser_error(path, str(exc))) from None
    _resolve_tls_files(cfg, file.resolve().parent)
    return cfg


def _parser_error(path: str, text: str) -> str:
    """zenoh's (multi-line) parser message as one ``FILE[:LINE:COL]: error:`` line."""
    at = _PARSER_AT.search(text)
    why = _PARSER_WHY.search(text)
    where = f"{path}:{at.group(1)}:{at.group(2)}" if at else path
    reason = why.group(1) if why else " ".join(text.split())[:200]
    return f"{where}: error: not a valid zenoh configuration: {reason}"


def check_config_file(path: str, parsed: zenoh.Config | None = None) -> None:
    """UserError when ``path`` cannot be a zenoh configuration (missing, unreadable, not JSON5,
    a setting zenoh refuses), before anything starts. ``parsed``: ``path`` already parsed
    (``umbra.runtime.links.config_facts``), completed here instead of parsing it again."""
    build_config(Endpoints(), path, parsed=parsed)


#: Zenoh TLS settings that name files.
_TLS_FILES = (
    "root_ca_certificate",
    "listen_private_key",
    "listen_certificate",
    "connect_private_key",
    "connect_certificate",
)


def _resolve_tls_files(cfg: zenoh.Config, folder: Path) -> None:
    """Certificate and key paths relative to the configuration file's ``folder`` (as ``umbra
    keys`` writes them), so the folder can be copied anywhere."""
    for name in _TLS_FILES:
        key = f"transport/link/tls/{name}"
        value = json.loads(cfg.get_json(key))
        if isinstance(value, str) and value and not Path(value).is_absolute():
            cfg.insert_json5(key, json.dumps(str(folder / value)))


def build_config(
    endpoints: Endpoints,
    config_file: str | None = None,
    auth: dict[str, Any] | None = None,
    parsed: zenoh.Config | None = None,
) -> zenoh.Config:
    """A zenoh configuration for one process: ``config_file`` (JSON5, for TLS, access control,
    routers) when given, then our safety settings and exactly ``endpoints``; ``auth`` (the
    launcher's per-run credentials, ``umbra.runtime.links.auth``) adds password authentication and
    the graph's access-control rules. ``parsed``: ``config_file`` already parsed
    (``umbra.runtime.links.config_facts``), completed here in place instead of parsing it again."""
    stock = zenoh.Config()
    if parsed is not None:
        cfg = parsed
    else:
        cfg = read_user_config(config_file) if config_file else zenoh.Config()
    if auth is not None:
        apply_auth(cfg, auth)

    def unchanged(key: str) -> bool:
        same: bool = cfg.get_json(key) == stock.get_json(key)  # get_json is typed Any
        return same

    for i, text in enumerate(endpoints.listen + endpoints.connect):
        check_endpoint(text, f"endpoint {i + 1}")
    if unchanged("mode"):
        cfg.insert_json5("mode", _json("peer"))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("scouting/gossip/enabled", "false")
    cfg.insert_json5("listen/endpoints", _json(endpoints.listen))
    cfg.insert_json5("connect/endpoints", _json(endpoints.connect))
    if unchanged("connect/retry"):
        cfg.insert_json5(
            "connect/retry",
            _json(
                {
                    "period_init_ms": 250,
                    "period_max_ms": 1000,
                    "period_increase_factor": 2,
                }
            ),
        )
    if unchanged("transport/link/tx/lease"):
        cfg.insert_json5("transport/link/tx/lease", _json(LEASE_MS))
    if unchanged("transport/link/tx/keep_alive"):
        cfg.insert_json5("transport/link/tx/keep_alive", _json(KEEP_ALIVE))
    if unchanged("transport/unicast/accept_timeout"):
        cfg.insert_json5("transport/unicast/accept_timeout", _json(ACCEPT_TIMEOUT_MS))
    if unchanged("transport/unicast/accept_pending"):
        cfg.insert_json5("transport/unicast/accept_pending", _json(ACCEPT_PENDING))
    if unchanged("transport/shared_memory/enabled"):
        cfg.insert_json5("transport/shared_memory/enabled", "true")
    return cfg


def describe(cfg: zenoh.Config) -> str:
    """One line naming mode and endpoints, for the log."""
    mode = json.loads(cfg.get_json("mode")) or "peer"
    listen = json.loads(cfg.get_json("listen/endpoints"))
    connect = json.loads(cfg.get_json("connect/endpoints"))
    return (
        f"zenoh {mode}: listen {', '.join(listen) or '-'}; "
        f"connect {', '.join(connect) or '-'}; scouting off"
    )
