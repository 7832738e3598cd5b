"""Who produced a sample: the zenoh session of each process of the graph, as its token says.

Every process holds one liveliness token, ``P/_alive/<process>/<marker>/<session>/<proof>``,
whose ``session`` chunk is the zenoh id of its session, and stamps each sample it publishes with
the same id (zenoh's ``source_info``). A consumer accepts a sample of a link only when it comes
from the live session of the process the graph names as the link's producer:

* a session is live from its token's appearance until its disappearance; a second token of the
  same process while one is live is a conflict (counted, ignored): the first stays in charge;
* a process whose token disappeared is gone and stays gone until a token of it appears again —
  samples never bring it back, whoever sends them (a process on this host whose token went while
  it lives is late, not gone, and keeps its live session: ``umbra.runtime.links.late``);
* sequence numbers are tracked per session, as its token names it: a new session of a producer
  (the same zenoh id started again too: its marker differs) starts a new count; the same token
  back after its link was lost goes on with the old one.

On its own a session id is a claim (a peer can copy it); what makes it an identity is that zenoh
authenticates the sessions (per-run user names under the launcher, user names derived from the
user's secret by hand, certificates across hosts) and the access-control rules derived from the
graph (``umbra.runtime.links.acl``) let each process publish only its own outputs and declare only
its own token. With credentials, ``proof`` is a keyed hash of the token's other chunks (``sign``,
the key comes with the credentials): a token without a valid one is counted and ignored, so a
peer that gets past zenoh's checks on its own claim (the side of a link that shows no password
is known by the zenoh id it says it has) still cannot make a process of the graph appear.
Without credentials (``--insecure``) the proof is ``none`` and not checked.
"""

from __future__ import annotations

import hashlib
import hmac
import threading
from dataclasses import dataclass, field
from typing import NamedTuple

ALIVE = "_alive"
#: ``proof`` of a token when there is no key to sign it with.
NO_PROOF = "none"
#: Hex digits of a token's proof.
PROOF_HEX = 32


class Token(NamedTuple):
    """The chunks of a liveliness token's key after ``P/_alive/``."""

    process: str
    marker: str
    session: str
    proof: str = NO_PROOF


def sign(key: str | None, process: str, marker: str, session: str) -> str:
    """The proof of a token of ``process`` with ``marker`` and ``session`` under ``key`` (hex;
    ``NO_PROOF`` when there is no key)."""
    if not key:
        return NO_PROOF
    text = f"{process}/{marker}/{session}".encode()
    return hmac.new(bytes.fromhex(key), text, hashlib.sha256).hexdigest()[:PROOF_HEX]


def proven(key: str | None, token: Token) -> bool:
    """Whether ``token`` carries the proof ``key`` gives it (always, when there is no key)."""
    if not key:
        return True
    expected = sign(key, token.process, token.marker, token.session)
    return hmac.compare_digest(expected, token.proof)


def alive_key(
    prefix: str,
    process: str,
    marker: str = "none",
    session: str = "none",
    proof: str = NO_PROOF,
) -> str:
    """Key of the liveliness token of ``process`` (its session's zenoh id, then its proof)."""
    return f"{prefix}/{ALIVE}/{process}/{marker}/{session}/{proof}"


def alive_pattern(prefix: str) -> str:
    """Key expression of every token under ``prefix``."""
    return f"{prefix}/{ALIVE}/*/*/*/*"


def parse_alive_key(key: str) -> Token | None:
    """The chunks of a token key; None when it is not one of ours.

    Read from the end (``.../_alive/PROCESS/MARKER/SESSION/PROOF``), so a key prefix that itself
    holds an ``_alive`` chunk (``--prefix umbra/_alive``) still names its processes."""
    parts = key.split("/")
    if len(parts) < 5 or parts[-5] != ALIVE:
        return None
    token = Token(*parts[-4:])
    if not all(token):
        return None
    return token


@dataclass
class Sessions:
    """The live token of each process, as tokens come and go (any thread).

    ``current`` holds the live token itself, one object per session: the same object again when
    a session comes back after its link was lost (its count goes on), a new one for a new
    session, even one with the same zenoh id (a process started again by hand: its marker
    differs), so ``is`` tells a new session from the one already seen."""

    current: dict[str, Token] = field(default_factory=dict)
    #: the latest live token of each process, kept after it is gone
    latest: dict[str, Token] = field(default_factory=dict)
    gone: set[str] = field(default_factory=set)
    conflicts: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def session_of(self, process: str) -> str | None:
        """Zenoh id of the live session of ``process`` (None when it has none)."""
        token = self.current.get(process)  # one dict read: atomic, no lock
        return None if token is None else token.session

    def live_sessions(self) -> list[str]:
        """Zenoh ids of every live process's session."""
        return [token.session for token in list(self.current.values())]

    def is_live(self, token: Token) -> bool:
        """Whether ``token`` is the live token of its process."""
        return self.current.get(token.process) == token

    def token_up(self, token: Token) -> bool:
        """A token appeared; True when it is now (or still) the live one of its process."""
        with self._lock:
            held = self.current.get(token.process)
            if held is not None:
                if held == token:
                    return True
                self.conflicts += 1
                return False
            latest = self.latest.get(token.process)
            if latest != token:
                latest = self.latest[token.process] = Token(*token)  # a new session: a new count
            self.current[token.process] = latest
            self.gone.discard(token.process)
            return True

    def token_down(self, token: Token) -> bool:
        """A token disappeared; True when it was the live one (its process is now gone)."""
        with self._lock:
            if self.current.get(token.process) != token:
                return False
            del self.current[token.process]
            self.gone.add(token.process)
            return True
