"""One browser, one operator: the viewer cookie the server gives each browser (pure).

Every browser gets a random viewer id in a cookie on its first request; every page of the server
it opens then speaks for the same operator (:mod:`umbra.modules.operator.control`). Pages are told
only names, never another browser's id; the id is kept as a hash (:func:`viewer_key`).
"""

from __future__ import annotations

import hashlib
import re
import secrets

VIEWER_COOKIE = "umbra_viewer"
#: ASGI scope key under which the gate leaves the request's viewer key ("" none)
VIEWER_SCOPE = "umbra.viewer"


def new_viewer_id() -> str:
    """A fresh viewer cookie value (random, URL-safe)."""
    return secrets.token_urlsafe(18)


def viewer_key(cookie: str | None) -> str:
    """The key of a browser from its viewer cookie ("" for none or a malformed one): a hash,
    so that logs and the control table never hold the cookie itself."""
    if not cookie or not re.fullmatch(r"[A-Za-z0-9_-]{16,64}", cookie):
        return ""
    return hashlib.sha256(cookie.encode()).hexdigest()[:16]
