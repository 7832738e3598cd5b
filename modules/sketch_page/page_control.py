"""The /sketch page's control, decided in ``step``: which browsers are on the page, who holds
control (the server's table, shared with the console), each request's decision, and the pause
of a path whose page went silent (a mixin of
:class:`~umbra.modules.sketch_page.sketch_page.SketchPage`).
"""

from __future__ import annotations

import math
import secrets
from typing import Any

from umbra.connectors.messages import Text
from umbra.modules.operator.control import Decision
from umbra.modules.sketch.command_text import parse
from umbra.modules.sketch.messages import VcrState
from umbra.modules.sketch_page.page_web import PageRequest
from umbra.modules.trajectory.vcr import STARTS


class PageControl:
    """Control of the /sketch page (``step`` side); state lives on the SketchPage."""

    _sessions: dict[str, str]
    _control: Any
    _seen: dict[str, tuple[float, str]]

    def _sync_sessions(self, wall: float) -> dict[str, float]:
        """Join the browsers whose pages poll, let go of those silent for ``lost_after``;
        returns each seen browser's last contact (monotonic s)."""
        with self._seen_lock:
            seen = dict(self._seen)
        gone = []
        for viewer, (last, host) in seen.items():
            if wall - last <= self.params.lost_after:
                self._session(viewer, host)
                continue
            gone.append(viewer)
            if viewer in self._sessions:
                self._leave(viewer, wall - last)
        with self._seen_lock:  # forget them, unless they came back meanwhile
            for viewer in gone:
                if self._seen.get(viewer) == seen[viewer]:
                    del self._seen[viewer]
        return {viewer: last for viewer, (last, _) in seen.items()}

    def _session(self, viewer: str, host: str) -> str:
        """The browser's session in the control table (joined on its first contact)."""
        session = self._sessions.get(viewer)
        if session is None:
            session = f"sketch-{secrets.token_hex(4)}"
            name = self._control.name_in(viewer) or f"sketch viewer {next(self._numbers)} ({host})"
            self._control.join(session, name, viewer, lead=False)  # told by browser
            self._sessions[viewer] = session
            self.log.info("%s opened the Active Sketch page", name)
        return session

    def _leave(self, viewer: str, silent: float) -> None:
        session = self._sessions.pop(viewer)
        name = self._control.sessions.get(session, session)
        freed = self._control.leave(session)
        self.log.info(
            "%s: no poll of the Active Sketch page for %.1f s: gone%s",
            name,
            silent,
            "; control is free" if freed else "",
        )

    def _refuse(self, name: str, message: str) -> Decision:
        self._control_refused += 1
        self.log.warning("SketchPage %s: %s: %s", self.name, name, message)
        return Decision(False, message)

    def _decide(self, request: PageRequest, wall: float) -> Decision:
        """Take / release control, or send a command if the request's browser holds control."""
        if not request.viewer:
            return self._refuse(
                f"a client at {request.host}",
                "refused: the request carried no viewer cookie: open the page /sketch in a "
                "browser (its requests carry the cookie the server gave it)",
            )
        session = self._session(request.viewer, request.host)
        name = self._control.sessions[session]
        if request.kind in ("take", "release"):
            take = request.kind == "take"
            decision = self._control.take(session) if take else self._control.release(session)
            if not decision.ok:
                return self._refuse(name, decision.message)
            self.log.info("SketchPage %s: %s", self.name, decision.message)
            return decision
        cmd = parse(request.text)
        words = request.text.split()
        what = " ".join(words[:2]) if cmd.verb in ("vcr", "plan") else words[0]
        decision = self._control.may_command(session, what)
        if not decision.ok:
            return self._refuse(name, decision.message)
        if cmd.verb == "vcr" and cmd.action != "speed":
            self._driver = (
                request.viewer if cmd.action in STARTS else None
            )  # a page gone silent then pauses it
        self.command.send(Text(text=request.text, origin=self._command_origin()))
        self._sent += 1
        return Decision(True, f"sent {what}")

    def _publish_control(self) -> None:
        """Who holds control, each browser's name, the refusals (for the web thread; the
        browser keys never leave the server)."""
        c = self._control
        names = {v: c.sessions.get(s, "") for v, s in self._sessions.items()}
        refused = self._refused + self._control_refused
        key = (c.holder_name(), c.holder_browser(), refused, tuple(sorted(names.items())))
        if key != self._control_key:
            self._control_key = key
            self._control_view.put(
                {"holder": key[0], "holder_browser": key[1], "refused": refused, "names": names}
            )

    def _watch_page(self, vcr: VcrState | None, seen: dict[str, float], wall: float) -> None:
        """Pause a path set moving from this page once that browser's page has not polled
        for ``lost_after``."""
        if self._driver is None:
            return
        silent = wall - seen.get(self._driver, -math.inf)
        moving = vcr is not None and vcr.mode in ("playing", "backing", "seeking", "gripping")
        if moving and silent > self.params.lost_after:
            self._driver = None
            self._lost += 1
            self.log.warning(
                "SketchPage %s: the page that set %s moving has not polled for %.1f s while "
                "it was %s: pausing it",
                self.name,
                vcr.path_id,
                silent,
                vcr.mode,
            )
            self.command.send(Text(text="vcr pause", origin=self._command_origin()))
