"""The live server's door: the per-run token, ``Host`` and ``Origin``, checked on the upgrade.

A viewer's WebSocket upgrade request is answered ``101`` only when

- the address carries the run's token (``?token=...``, compared in constant time),
- ``Host`` names this server (``127.0.0.1:PORT``, ``localhost:PORT``... as the operator's pages
  answer to: DNS rebinding gets nothing), and
- ``Origin`` is absent (a client that is not a browser) or one of the viewer pages allowed
  (``https://app.foxglove.dev`` and the ``--foxglove-origin`` ones);

else it gets ``421`` (Host) or ``403`` and the connection closes. The rules are the operator pages'
own (``umbra.connectors.access.secret`` and ``hosts``), not a second copy.

Why the protocol is served here and not by Foxglove's SDK behind a proxy: the SDK's server
(``foxglove-sdk`` 0.30) has no hook that sees a connecting client's request, so it had to listen on
a loopback port of its own behind a proxy, and that port let every local user watch the run
without the token. Here the socket that checks the token is the only one that serves the data.
"""

from __future__ import annotations

from collections.abc import Iterable
from urllib.parse import parse_qs, urlsplit

from umbra.connectors.access.hosts import host_allowed, origin_allowed
from umbra.connectors.access.secret import TOKEN_QUERY, token_matches

#: Viewer pages allowed by default (Foxglove's web app).
DEFAULT_ORIGINS = ("https://app.foxglove.dev",)


def origin_netlocs(origins: Iterable[str]) -> frozenset[str]:
    """``host[:port]`` of each allowed viewer page origin (``scheme://host[:port]``)."""
    return frozenset(urlsplit(o.strip()).netloc.lower() for o in origins if o.strip())


def refusal(
    target: str,
    host: str | None,
    origin: str | None,
    token: str,
    hosts: frozenset[str],
    origins: frozenset[str],
) -> tuple[int, str] | None:
    """``(status, why)`` when an upgrade request for ``target`` (path and query) with these
    ``Host`` and ``Origin`` headers (None: absent) may not pass, else None."""
    if not host_allowed(host, hosts):
        return 421, f"Host {host!r} is not this server"
    if not origin_allowed(origin, origins | hosts):
        return 403, f"Origin {origin!r} is not an allowed viewer page"
    given = parse_qs(urlsplit(target).query).get(TOKEN_QUERY, [None])[0]
    if not token_matches(token, given):
        return 403, "the address's token is missing or wrong"
    return None
