"""Several viewers, one operator: who holds control of the pages of one web server.

Any number of sessions (a console page's websocket, an Active Sketch page's polls) watch; at most
one operator holds control. Taking control is refused while another operator holds it (the
holder releases it, or disconnects). Commands from a session without control are refused and
counted. Pure: no threads, no clock.

One operator is one browser: a session may name the browser it comes from (a key derived from
the server's viewer cookie, :func:`umbra.modules.operator.access.viewer_key`), and every session of
the browser that holds control holds it too, so control taken on the console is control on the
sketch page of the same browser, and the other way round. A session without a browser key
("") is an operator on its own. The holder recorded is the browser's first *leading* session
(a console page: it compares the holder with its own session to say "(you)"), else its first
session (a sketch page joins as a follower: it is told by browser); when it leaves, control
passes to the browser's next session, and is free once the browser's last session has gone.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Decision:
    """The outcome of a request: ``ok``, and the message for the page and the log."""

    ok: bool
    message: str


@dataclass
class ControlArbiter:
    """Sessions by id, the browser of each, the holder of control, and the refusals."""

    sessions: dict[str, str] = field(default_factory=dict)  #: id -> display name
    browsers: dict[str, str] = field(default_factory=dict)  #: id -> browser key ("" none)
    followers: set[str] = field(default_factory=set)  #: sessions that joined with lead=False
    holder: str | None = None
    refused: int = 0
    #: True once any person has held control during the run (the simulated operator steps aside)
    person_acted: bool = False

    def join(self, session: str, name: str, browser: str = "", lead: bool = True) -> None:
        """A page connected (``browser``: the key of the browser it runs in, "" unknown;
        ``lead``: the page shows control by comparing the holder with its own session, so it
        stands for its browser as the holder recorded)."""
        self.sessions[session] = name
        self.browsers[session] = browser
        if not lead:
            self.followers.add(session)
        elif browser and self.holder in self.followers and self.holder_browser() == browser:
            self.holder = session

    def leave(self, session: str) -> bool:
        """A page disconnected; True when control is now free (it was the browser's last
        session holding it)."""
        self.sessions.pop(session, None)
        browser = self.browsers.pop(session, "")
        self.followers.discard(session)
        if self.holder != session:
            return False
        self.holder = self._first_of(browser)
        return self.holder is None

    def holds(self, session: str) -> bool:
        """Whether ``session`` holds control (its own, or its browser's). Not counted."""
        if self.holder is None or session not in self.sessions:
            return False
        if session == self.holder:
            return True
        browser = self.browsers.get(session, "")
        return bool(browser) and browser == self.browsers.get(self.holder, "")

    def take(self, session: str) -> Decision:
        """``session`` asks for control."""
        if session not in self.sessions:
            self.refused += 1
            return Decision(False, "unknown session: reload the page")
        if self.holds(session):
            return Decision(True, "you already hold control")
        if self.holder is not None:
            self.refused += 1
            return Decision(
                False,
                f"refused: {self.holder_name()} holds control; they must release it first",
            )
        self.holder = self._first_of(self.browsers.get(session, "")) or session
        self.person_acted = True
        return Decision(True, f"{self.sessions[session]} took control")

    def release(self, session: str) -> Decision:
        """``session`` gives control back (for its whole browser)."""
        if not self.holds(session):
            self.refused += 1
            return Decision(False, "refused: you do not hold control")
        self.holder = None
        return Decision(True, f"{self.sessions.get(session, session)} released control")

    def may_command(self, session: str, what: str) -> Decision:
        """Whether ``session`` may send the command ``what`` (refusals are counted)."""
        if self.holds(session):
            return Decision(True, "")
        self.refused += 1
        if self.holder is None:
            return Decision(False, f"refused {what}: take control first")
        return Decision(False, f"refused {what}: {self.holder_name()} holds control")

    def holder_name(self) -> str:
        """Display name of the holder ("" when nobody holds control)."""
        return "" if self.holder is None else self.sessions.get(self.holder, self.holder)

    def holder_browser(self) -> str:
        """Browser key of the holder ("" when nobody holds control, or it has none)."""
        return "" if self.holder is None else self.browsers.get(self.holder, "")

    def name_in(self, browser: str) -> str:
        """The name of the browser's first session ("" for none, or no browser key)."""
        first = self._first_of(browser)
        return "" if first is None else self.sessions[first]

    def _first_of(self, browser: str) -> str | None:
        """The browser's first leading session, else its first session (None: none)."""
        if not browser:
            return None
        mine = [s for s, b in self.browsers.items() if b == browser]
        leading = [s for s in mine if s not in self.followers]
        return next(iter(leading or mine), None)
