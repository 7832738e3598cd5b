"""Who may open the console: loopback is open, anything else needs an access token.

A token is a random URL-safe string printed at start (or read from a file the operator keeps).
The page is opened as ``http://HOST:PORT/?token=...`` (or any page of the server, e.g.
``/sketch?token=...``); the server then sets a cookie, so the page's own requests and its
websocket carry it.

Every browser also gets a viewer cookie (a random id, set by the server on its first request):
one browser is one operator, whichever of the server's pages it opens
(:mod:`modules.operator.control`). Pages are told only names, never another browser's id; the
id is kept as a hash (:func:`viewer_key`).
"""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import re
import secrets
from pathlib import Path

from connectors.errors import UserError

TOKEN_COOKIE = "umbra_token"
TOKEN_QUERY = "token"
VIEWER_COOKIE = "umbra_viewer"
#: ASGI scope key under which the server's gate leaves the request's viewer key ("" none)
VIEWER_SCOPE = "umbra.viewer"


def is_loopback(host: str) -> bool:
    """True for ``localhost`` and loopback addresses (127.0.0.0/8, ::1)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def resolve_token(host: str, token_file: str, where: str) -> str:
    """The token the server enforces ("" = none: loopback without a token file).

    ``token_file`` non-empty: its first line is the token (at least 16 characters). Listening
    beyond loopback without a file: a fresh random token (the caller prints it).
    """
    if token_file:
        path = Path(token_file).expanduser()
        try:
            token = path.read_text(encoding="utf-8").strip().splitlines()[0].strip()
        except (OSError, IndexError) as exc:
            raise UserError(
                f"{where}: token_file: expected a readable file whose first line is the access "
                f"token, found {type(exc).__name__}: {exc} ({path})"
            ) from None
        if len(token) < 16:
            raise UserError(
                f"{where}: token_file: expected a token of at least 16 characters, found "
                f"{len(token)} ({path})"
            )
        return token
    if is_loopback(host):
        return ""
    return secrets.token_urlsafe(18)


def token_matches(expected: str, given: str | None) -> bool:
    """Constant-time comparison; an empty ``expected`` lets everyone in."""
    if not expected:
        return True
    return given is not None and hmac.compare_digest(expected.encode(), given.encode())


def new_viewer_id() -> str:
    """A fresh viewer cookie value (random, URL-safe)."""
    return secrets.token_urlsafe(18)


def viewer_key(cookie: str | None) -> str:
    """The key of a browser from its viewer cookie ("" for none or a malformed one): a hash,
    so that logs and the control table never hold the cookie itself."""
    if not cookie or not re.fullmatch(r"[A-Za-z0-9_-]{16,64}", cookie):
        return ""
    return hashlib.sha256(cookie.encode()).hexdigest()[:16]
