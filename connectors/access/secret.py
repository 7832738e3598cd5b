"""The per-run access token of a run's servers (every page, route and socket needs it).

A token is a random URL-safe string made at start (or read from a file the operator keeps); a
page is opened as ``http://HOST:PORT/?token=...`` and the page server exchanges it for a cookie
(the web door's gate); the live server checks it on each upgrade. Loopback is no exception:
another user of the same machine, or a page open in the operator's browser, reaches 127.0.0.1
too.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from pathlib import Path

from umbra.connectors.errors import UserError

TOKEN_COOKIE = "umbra_token"
TOKEN_QUERY = "token"
#: header a client that is not a browser sends on a POST instead of its page's Origin
CSRF_HEADER = "x-umbra-csrf"
#: shortest token a token file may hold [characters]
MIN_TOKEN_CHARS = 16


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback addresses (127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def resolve_token(token_file: str, where: str) -> str:
    """The token the server enforces: the first line of ``token_file`` (at least
    :data:`MIN_TOKEN_CHARS` characters), else a fresh random one (the caller prints it)."""
    if not token_file:
        return secrets.token_urlsafe(24)
    path = Path(token_file).expanduser()
    try:
        token = path.read_text(encoding="utf-8").strip().splitlines()[0].strip()
    except (OSError, IndexError, UnicodeDecodeError) as exc:
        raise UserError(
            f"{where}: token_file: expected a readable file whose first line is the access "
            f"token, found {type(exc).__name__}: {exc} ({path})"
        ) from None
    if len(token) < MIN_TOKEN_CHARS or not token.isascii() or not token.isprintable():
        raise UserError(
            f"{where}: token_file: expected a token of at least {MIN_TOKEN_CHARS} printable "
            f"ASCII characters, found {len(token)} characters ({path})"
        )
    return token


def token_matches(expected: str, given: str | None) -> bool:
    """Constant-time comparison; no token given, or none expected, never matches."""
    if not expected or given is None:
        return False
    return hmac.compare_digest(expected.encode(), given.encode("utf-8", "replace"))
