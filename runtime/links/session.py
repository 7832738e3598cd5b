"""Opening a zenoh session, with failures a user can fix reported as such, and waiting for it
to reach a run's processes."""

from __future__ import annotations

import logging
import threading
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


#: Longest a session's close is waited for [s]: a little over zenoh's handshake deadline
#: (``config.ACCEPT_TIMEOUT_MS``), which a half-open connection from a stranger makes it wait.
CLOSE_WAIT_S = 3.0


def close_session(
    session: zenoh.Session, log: logging.Logger, timeout_s: float = CLOSE_WAIT_S
) -> bool:
    """Close ``session``, waiting at most ``timeout_s`` [s] (in a thread of its own: a close that
    hangs on a stranger's connection must not hold the process's exit); True when it closed."""
    done = threading.Event()

    def close() -> None:
        try:
            session.close()
        except Exception as exc:  # already closed, or zenoh's runtime going down
            log.debug("zenoh session close: %s", exc)
        finally:
            done.set()

    threading.Thread(target=close, name="umbra-session-close", daemon=True).start()
    if not done.wait(timeout_s):
        log.warning(
            "the zenoh session did not close within %.1f s (a peer's connection holds it): "
            "leaving it behind",
            timeout_s,
        )
        return False
    return True
