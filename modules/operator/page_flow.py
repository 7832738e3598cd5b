"""How much the console sends a page before the page has shown it: never a queue.

A page says what it has shown: ``painted`` for each video frame (drawn, or overtaken by a newer
one), ``seen`` with the version of each state it has drawn. The server keeps at most
:data:`~umbra.connectors.limits.MAX_PAGE_IN_FLIGHT` frames and as many states on their way to a page
and not yet acknowledged, and sends the newest of each when one is acknowledged (the latest wins). A
page on a starved machine, which shows a message seconds after it arrives, therefore falls behind by
two messages, not by everything sent meanwhile; and the run's last state reaches it, and is known to
have been shown, before the console's process ends (``ConsoleApp.flush_final``).

A client that has never acknowledged a kind is not held back by it (a script reading the states, an
older page): its states come at the console's rate, and its frames at one per
:data:`~umbra.connectors.limits.PAGE_ACK_TIMEOUT_S` while it has two unacknowledged. Once it has
acknowledged one, nothing expires: a page whose acknowledgements stop hears nothing more and its own
silent-socket check (``PAGE_SILENT_S``) opens a new socket.
"""

from __future__ import annotations

import asyncio
import time

from umbra.connectors.limits import MAX_PAGE_IN_FLIGHT, PAGE_ACK_TIMEOUT_S


class InFlight:
    """Messages of one kind sent to one page and not yet acknowledged, by version (web thread
    only). ``paced``: a client that never acknowledges gets one more per ``PAGE_ACK_TIMEOUT_S``
    (frames); otherwise it is not held back (states)."""

    def __init__(self, paced: bool) -> None:
        self.paced = paced
        self.versions: list[int] = []  #: sent and not yet acknowledged, oldest first
        self.newest_sent = 0  #: the newest version sent (0: none yet)
        self.acknowledged = 0  #: the newest version the page acknowledged (0: none yet)
        self.acks = False  #: the page has acknowledged one of this kind
        self.deadline = 0.0
        self.event = asyncio.Event()  #: set when an acknowledgement frees room

    def can_send(self) -> bool:
        if not self.acks:
            if not self.paced:
                return True
            if self.versions and time.monotonic() > self.deadline:
                self.versions.clear()  # a client that does not acknowledge: paced, not stopped
        return len(self.versions) < MAX_PAGE_IN_FLIGHT

    def sent(self, version: int) -> None:
        self.versions.append(version)
        self.newest_sent = version
        self.deadline = time.monotonic() + PAGE_ACK_TIMEOUT_S
        self.event.clear()

    def acknowledge(self, version: int | None = None) -> None:
        """The page showed ``version`` and every one before it (None: the oldest one sent)."""
        self.acks = True
        if version is None:
            self.versions = self.versions[1:]
        else:
            self.acknowledged = max(self.acknowledged, version)
            self.versions = [v for v in self.versions if v > version]
        self.event.set()

    def shown(self, version: int) -> bool:
        """The page acknowledged ``version`` (or a newer one)."""
        return self.acknowledged >= version


class PageFlow:
    """One page's frames and states on their way (web thread writes; ``flush_final`` reads
    ``states`` from the stopping module's thread)."""

    def __init__(self) -> None:
        self.frames = InFlight(paced=True)
        self.states = InFlight(paced=False)

    def final_done(self, version: int) -> bool:
        """The run's last state (``version``) has been shown by this page, or sent to a client
        that does not say what it showed."""
        if self.states.acks:
            return self.states.shown(version)
        return self.states.newest_sent >= version
