"""Opening a zenoh session, with failures a user can fix reported as such, and waiting for it
to reach a run's processes."""

from __future__ import annotations

import time

import zenoh

from umbra.connectors.errors import UserError
from umbra.runtime.links.config import describe


def open_session(config: zenoh.Config) -> zenoh.Session:
    """An open zenoh session for ``config``; UserError when zenoh refuses it (an endpoint already
    in use, a bad address, a TLS file that cannot be read...)."""
    try:
        return zenoh.open(config)
    except Exception as exc:  # zenoh raises ZError with its own message
        hint = ""
        if "Address already in use" in str(exc):
            hint = (
                "; another program (another graph, a zenohd router) holds that port: give this"
                " process another with --listen ENDPOINT (and the others --connect to it), or"
                " name them under `links:` in the graph"
            )
        raise UserError(
            f"cannot open the zenoh session ({describe(config)}): {exc}{hint}"
        ) from None


#: How often a waiting session's transports are counted [s].
JOIN_POLL_S = 0.02


def wait_joined(session: zenoh.Session, count: int, timeout_s: float) -> int:
    """Wait up to ``timeout_s`` [s] until ``session`` has a transport to ``count`` peers (a
    run's processes); the number it has then (fewer when the time ran out)."""
    deadline = time.monotonic() + timeout_s
    while True:
        joined = len(list(session.info.transports()))
        if joined >= count or time.monotonic() > deadline:
            return joined
        time.sleep(JOIN_POLL_S)
