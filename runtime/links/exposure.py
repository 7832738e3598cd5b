"""Secure by default beyond loopback: no plain-text endpoint off this host unless asked for.

An endpoint on a loopback address (``127.0.0.0/8``, ``::1``, ``localhost``) or a Unix socket
(``unixsock-stream/PATH``) is reachable from this host only; any other address (``0.0.0.0`` and
``[::]`` included) is reachable from the network, where a link must use TLS (``tls/`` or
``quic/`` endpoints, with the certificates that ``umbra keys`` makes) so that only the graph's
processes can open it. ``--insecure`` lifts this.
"""

from __future__ import annotations

from pathlib import Path

from umbra.connectors.errors import UserError
from umbra.runtime.graph.names import plain_beyond_host

HOW_TO_TLS = (
    "make a CA, a certificate per process and the graph's access rules with "
    "`umbra keys GRAPH --out keys/`, copy keys/ to each host, then run each process with "
    "`--zenoh-config keys/` and TLS endpoints (e.g. `--listen tls/0.0.0.0:7447`, "
    "`--connect tls/HOST:7447`); or add --insecure to accept plain TCP beyond loopback "
    "(anyone who reaches the endpoint can then drive the graph)"
)


def check_exposure(listen: list[str], connect: list[str], insecure: bool, where: str) -> None:
    """UserError naming the first plain endpoint beyond loopback (unless ``insecure``);
    ``where`` says where the endpoints come from (``--listen/--connect``, a file)."""
    if insecure:
        return
    for kind, endpoints in (("listen on", listen), ("connect to", connect)):
        for endpoint in endpoints:
            if not plain_beyond_host(endpoint):
                continue
            raise UserError(
                f"{where}: error: refusing to {kind} `{endpoint}` without TLS: it is reachable "
                f"beyond this host, and anyone who reaches it could drive the graph. To run "
                f"across hosts securely, {HOW_TO_TLS}"
            )


def config_for(path: str, process: str) -> str:
    """The zenoh configuration file of ``process``: ``path`` itself, or ``path/PROCESS.json5``
    when ``path`` is a folder written by ``umbra keys``."""
    folder = Path(path)
    if not folder.is_dir():
        return path
    file = folder / f"{process}.json5"
    if not file.is_file():
        raise UserError(
            f"{path}: error: no zenoh configuration for process `{process}` in this folder "
            f"(expected {file.name}; write the folder with `umbra keys GRAPH --out {path}`)"
        )
    return str(file)
