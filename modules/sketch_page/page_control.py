"""The /sketch page's control, decided in ``step``: which browsers are on the page, who holds
control (the server's table, shared with the console), each request's decision, and the pause
of a path whose page went silent (a part that
:class:`~umbra.modules.sketch_page.sketch_page.SketchPage` owns).
"""

from __future__ import annotations

import itertools
import math
import secrets
from typing import TYPE_CHECKING, Any

from umbra.connectors.messages import Text
from umbra.connectors.path_messages import VCR_GOING, VcrState
from umbra.modules.operator.control import Decision
from umbra.modules.sketch.command_text import parse
from umbra.modules.sketch_page.page_web import PageRequest, PageWeb
from umbra.modules.trajectory.vcr import STARTS

if TYPE_CHECKING:
    from umbra.modules.sketch_page.sketch_page import SketchPage


class PageControl:
    """Control of the /sketch page (``step`` side): reads the page module's control table,
    parameters and log and sends on its ``command`` output; takes the browsers seen from the
    web side ``web`` and gives it the control view. Keeps each browser's session, the browser
    that set a path moving, and the counts of commands sent, refused and paused paths."""

    def __init__(self, page: SketchPage, web: PageWeb) -> None:
        self._p = page
        self._web = web
        self._sessions: dict[str, str] = {}  #: viewer key -> session in the control table
        self._numbers = itertools.count(1)
        self._driver: str | None = None  #: viewer whose VCR command set the path moving
        self._control_key: tuple[Any, ...] | None = None
        self.sent = 0  #: commands sent
        self.control_refused = 0  #: requests refused for want of control
        self.lost = 0  #: paths paused because the page that set them moving went silent

    def sync_sessions(self, wall: float) -> dict[str, float]:
        """Join the browsers whose pages poll, let go of those silent for ``lost_after``;
        returns each seen browser's last contact (monotonic s)."""
        with self._web.seen_lock:
            seen = dict(self._web.seen)
        gone = []
        for viewer, (last, host) in seen.items():
            if wall - last <= self._p.params.lost_after:
                self._session(viewer, host)
                continue
            gone.append(viewer)
            if viewer in self._sessions:
                self._leave(viewer, wall - last)
        with self._web.seen_lock:  # forget them, unless they came back meanwhile
            for viewer in gone:
                if self._web.seen.get(viewer) == seen[viewer]:
                    del self._web.seen[viewer]
        return {viewer: last for viewer, (last, _) in seen.items()}

    def _session(self, viewer: str, host: str) -> str:
        """The browser's session in the control table (joined on its first contact)."""
        session = self._sessions.get(viewer)
        if session is None:
            session = f"sketch-{secrets.token_hex(4)}"
            name = self._p._control.name_in(viewer)
            if not name:
                name = f"sketch viewer {next(self._numbers)} ({host})"
            self._p._control.join(session, name, viewer, lead=False)  # told by browser
            self._sessions[viewer] = session
            self._p.log.info("%s opened the Active Sketch page", name)
        return session

    def leave_all(self) -> None:
        """Every browser of this page leaves the control table (the run ends)."""
        for session in self._sessions.values():
            self._p._control.leave(session)
        self._sessions.clear()

    def _leave(self, viewer: str, silent: float) -> None:
        session = self._sessions.pop(viewer)
        name = self._p._control.sessions.get(session, session)
        freed = self._p._control.leave(session)
        self._p.log.info(
            "%s: no poll of the Active Sketch page for %.1f s: gone%s",
            name,
            silent,
            "; control is free" if freed else "",
        )

    def _refuse(self, name: str, message: str) -> Decision:
        self.control_refused += 1
        self._p.log.warning("SketchPage %s: %s: %s", self._p.name, name, message)
        return Decision(False, message)

    def decide(self, request: PageRequest, wall: float) -> Decision:
        """Take / release control, or send a command if the request's browser holds control."""
        if not request.viewer:
            return self._refuse(
                f"a client at {request.host}",
                "refused: the request carried no viewer cookie: open the page /sketch in a "
                "browser (its requests carry the cookie the server gave it)",
            )
        session = self._session(request.viewer, request.host)
        name = self._p._control.sessions[session]
        if request.kind in ("take", "release"):
            take = request.kind == "take"
            decision = self._p._control.take(session) if take else self._p._control.release(session)
            if not decision.ok:
                return self._refuse(name, decision.message)
            self._p.log.info("SketchPage %s: %s", self._p.name, decision.message)
            return decision
        cmd = parse(request.text)
        words = request.text.split()
        what = " ".join(words[:2]) if cmd.verb in ("vcr", "plan") else words[0]
        decision = self._p._control.may_command(session, what)
        if not decision.ok:
            return self._refuse(name, decision.message)
        if cmd.verb == "vcr" and cmd.action != "speed":
            self._driver = (
                request.viewer if cmd.action in STARTS else None
            )  # a page gone silent then pauses it
        self._p.command.send(Text(text=request.text, origin=self._p._command_origin()))
        self.sent += 1
        return Decision(True, f"sent {what}")

    def publish_control(self) -> None:
        """Who holds control, each browser's name, the refusals (for the web thread; the
        browser keys never leave the server)."""
        c = self._p._control
        names = {v: c.sessions.get(s, "") for v, s in self._sessions.items()}
        refused = self._web.refused + self.control_refused
        key = (c.holder_name(), c.holder_browser(), refused, tuple(sorted(names.items())))
        if key != self._control_key:
            self._control_key = key
            self._web.control_view.put(
                {"holder": key[0], "holder_browser": key[1], "refused": refused, "names": names}
            )

    def watch_page(self, vcr: VcrState | None, seen: dict[str, float], wall: float) -> None:
        """Pause a path set moving from this page once that browser's page has not polled
        for ``lost_after``."""
        if self._driver is None:
            return
        silent = wall - seen.get(self._driver, -math.inf)
        if vcr is None or vcr.mode not in VCR_GOING:
            return  # not under way, or already stopping
        if silent > self._p.params.lost_after:
            self._driver = None
            self.lost += 1
            self._p.log.warning(
                "SketchPage %s: the page that set %s moving has not polled for %.1f s while "
                "it was %s: pausing it",
                self._p.name,
                vcr.path_id,
                silent,
                vcr.mode,
            )
            self._p.command.send(Text(text="vcr pause", origin=self._p._command_origin()))
