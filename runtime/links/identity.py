"""Who produced a sample: the zenoh session of each process of the graph, as its token says.

Every process holds one liveliness token, ``P/_alive/<process>/<marker>/<session>``, whose last
chunk is the zenoh id of its session, and stamps each sample it publishes with the same id (zenoh's
``source_info``). A consumer accepts a sample of a link only when it comes from the live session of
the process the graph names as the link's producer:

* a session is live from its token's appearance until its disappearance; a second token of the
  same process while one is live is a conflict (counted, ignored): the first stays in charge;
* a process whose token disappeared is gone and stays gone until a token of it appears again —
  samples never bring it back, whoever sends them;
* sequence numbers are tracked per session: a new session of a producer starts a new count.

On its own a session id is a claim (a peer can copy it); what makes it an identity is that zenoh
authenticates the sessions (per-run user names under the launcher, certificates across hosts) and
the access-control rules derived from the graph (``runtime.links.acl``) let each process publish
only its own outputs and declare only its own token.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

ALIVE = "_alive"


def alive_key(prefix: str, process: str, marker: str = "none", session: str = "none") -> str:
    """Key of the liveliness token of ``process`` (its session's zenoh id last)."""
    return f"{prefix}/{ALIVE}/{process}/{marker}/{session}"


def parse_alive_key(key: str) -> tuple[str, str, str] | None:
    """``(process, marker, session)`` of a token key; None when it is not one of ours.

    Read from the end (``.../_alive/PROCESS/MARKER/SESSION``), so a key prefix that itself holds
    an ``_alive`` chunk (``--prefix umbra/_alive``) still names its processes."""
    parts = key.split("/")
    if len(parts) < 4 or parts[-4] != ALIVE:
        return None
    process, marker, session = parts[-3:]
    if not (process and marker and session):
        return None
    return process, marker, session


@dataclass
class Sessions:
    """The live session of each process, as tokens come and go (any thread)."""

    live: dict[str, str] = field(default_factory=dict)
    gone: set[str] = field(default_factory=set)
    conflicts: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def token_up(self, process: str, session: str) -> bool:
        """A token of ``process`` appeared; True when it is now (or still) the live session."""
        with self._lock:
            current = self.live.get(process)
            if current is not None and current != session:
                self.conflicts += 1
                return False
            self.live[process] = session
            self.gone.discard(process)
            return True

    def token_down(self, process: str, session: str) -> bool:
        """A token of ``process`` disappeared; True when it was the live one (now gone)."""
        with self._lock:
            if self.live.get(process) != session:
                return False
            del self.live[process]
            self.gone.add(process)
            return True
