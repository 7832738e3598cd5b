"""Opening a zenoh session, with failures a user can fix reported as such."""

from __future__ import annotations

import zenoh

from connectors.errors import UserError
from runtime.links.config import describe


def open_session(config: zenoh.Config) -> zenoh.Session:
    """An open zenoh session for ``config``; UserError when zenoh refuses it (an endpoint already
    in use, a bad address, a TLS file that cannot be read...)."""
    try:
        return zenoh.open(config)
    except Exception as exc:  # zenoh raises ZError with its own message
        raise UserError(f"cannot open the zenoh session ({describe(config)}): {exc}") from None
