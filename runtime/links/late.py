"""Telling a peer that is starved from one that is gone.

Zenoh drops a link whose peer sent nothing for a lease (``umbra.runtime.links.config.LEASE_MS``),
and with it the peer's liveliness token. A process that the machine merely starves (a page's
process under ``nice`` on a loaded host, a process stopped by a debugger) is silent for that long
too, yet it is there and comes back with the same session. So when the token of a peer on this
host (its marker names its pid: ``umbra.runtime.links.pool.marker_pid``) goes while the OS says
the process lives, the peer is *late*, not gone: its links keep their state, its samples and
token are taken again when its link returns, and it is declared gone only when its process dies
(checked every ``LATE_CHECK_S``) or stays silent ``LATE_MAX_S`` (:data:`LATE_MAX_S`, the one
bound). A peer on another host (no pid to ask) is gone when its token goes.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from umbra.runtime.links.identity import Token
from umbra.runtime.links.pool import pid_alive

#: Longest [s] a peer on this host whose link was lost while its process lives is held late
#: before it is declared gone (a process starved by the machine's load comes back well within
#: it; a process that dies is declared gone at the next check, whatever this bound).
LATE_MAX_S = 10.0
#: How often [s] the pids of late peers are checked.
LATE_CHECK_S = 0.05


@dataclass
class _Late:
    token: Token
    pid: int
    since: float  #: monotonic [s]


class LatePeers:
    """Peers held late (any thread). ``on_gone(token)`` is called, on this class's thread, for a
    late peer whose process died or that stayed silent ``bound_s``."""

    def __init__(self, on_gone: Callable[[Token], None], bound_s: float = LATE_MAX_S) -> None:
        self._on_gone = on_gone
        self.bound_s = bound_s
        self._late: dict[str, _Late] = {}
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._closed = False
        self._thread: threading.Thread | None = None
        self.held = 0  #: times a peer was held late
        self.returned = 0  #: times a late peer came back (its token again)

    def hold(self, token: Token, pid: int | None) -> bool:
        """The live ``token`` went: True when its process (``pid``, None: not on this host)
        lives, which makes the peer late (watched) rather than gone. A peer in this very process
        (two sessions of one test) is never late: nothing starves one part of a process but not
        the other, so its token goes only because its session closed."""
        if pid is None or pid == os.getpid() or not pid_alive(pid):
            return False
        with self._lock:
            if self._closed:
                return False
            self._late[token.process] = _Late(token, pid, time.monotonic())
            self.held += 1
            if self._thread is None:
                self._thread = threading.Thread(target=self._watch, name="umbra-late", daemon=True)
                self._thread.start()
        self._wake.set()
        return True

    def back(self, token: Token) -> float | None:
        """``token`` appeared: how long [s] its process was late (None: it was not)."""
        with self._lock:
            late = self._late.get(token.process)
            if late is None or late.token != token:
                return None
            del self._late[token.process]
            self.returned += 1
        return time.monotonic() - late.since

    def late(self) -> dict[str, float]:
        """The late peers and for how long [s] each has been."""
        now = time.monotonic()
        with self._lock:
            return {name: now - late.since for name, late in self._late.items()}

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self._late.clear()
        self._wake.set()

    def _watch(self) -> None:
        while True:
            with self._lock:
                if self._closed:
                    return
                self._wake.clear()  # a hold after this sets it again: never missed
                now = time.monotonic()
                gone = [
                    late
                    for late in self._late.values()
                    if now - late.since >= self.bound_s or not pid_alive(late.pid)
                ]
                for late in gone:
                    del self._late[late.token.process]
                idle = not self._late
            for late in gone:
                self._on_gone(late.token)
            self._wake.wait(None if idle else LATE_CHECK_S)
