"""SketchPage: the Active Sketch page, /sketch on the umbra process's web server."""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import json
import math
import secrets
import threading
import time
from dataclasses import dataclass
from importlib import resources
from typing import Any

import cv2
from fastapi import Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from connectors import Input, Module, Output, Parameters, param
from connectors.limits import MAX_PAGE_CONNECTIONS
from connectors.messages import Status, Text
from connectors.sketch_messages import SketchPrimitive, StereoSnapshot, ToolPath, VcrState
from modules.operator.control import Decision
from modules.operator.mailbox import Lanes, Latest
from modules.operator.web_server import acquire_server, release_server
from modules.sketch.command_text import parse
from modules.sketch.stereo import StereoPair
from modules.sketch_page.page_state import page_state
from modules.webdoor.gate import Refusals
from modules.webdoor.secret import resolve_token
from modules.webdoor.viewer import VIEWER_SCOPE

MAX_COMMAND_CHARS = 2000
#: the web side waits at most this long for ``step`` to decide on a request [s]
REPLY_TIMEOUT_S = 5.0
#: VCR actions that set the path moving (a page that then goes silent pauses it)
_MOVING = ("play", "back", "resume", "seek")


def _static(name: str) -> str:
    return resources.files("modules.sketch_page").joinpath("static", name).read_text("utf-8")


@dataclass(frozen=True)
class _Request:
    """From the web thread to ``step``: a checked command (``kind`` "command", its ``text``)
    or a control request ("take" / "release"), the browser it came from (viewer key, "" none)
    and its address, and where ``step`` puts its :class:`Decision`."""

    viewer: str
    host: str
    kind: str
    text: str
    reply: concurrent.futures.Future


class SketchPage(Module):
    """The operator's Active Sketch page on the console's web server (``/sketch``).

    Shows the last snapshot pair side by side with SVG overlays: primitives dropped in both
    images, vertices dragged (the right-hand ones ride on their epipolar lines), reprojected
    3-D vertices, the macro menu, the planned path, the VCR buttons and speed. The page's
    actions come back as Sketch text commands (``modules/sketch/command_text.py``), checked here
    before they are queued; the module sends them on ``command`` (wire it to Sketch.console).
    The web side never touches the graph: it reads the latest messages through
    :class:`~modules.operator.mailbox.Latest` and queues requests in
    :class:`~modules.operator.mailbox.Lanes` (one per browser; the holder's first) that ``step``
    drains and answers.

    Several viewers, one operator, as on the console and with the same holder: the page uses
    the control table of its web server (``server.control``), so control taken on the console
    is control here and the other way round (one browser is one operator: the server's viewer
    cookie). Any number of browsers may watch; every command (snapshot, aim, zoom, place, plan,
    make_box, the VCR's play / pause / back / resume / speed / seek) passes only from the
    browser holding control; the rest are refused with the reason, on the page and in the log,
    and counted. The page shows who holds control, with Take / Release buttons; without a
    console in the graph the page is the only way in, and any viewer may take control while
    nobody holds it. A browser whose page has not polled for ``lost_after`` seconds has left
    (control held only there is free again). Beyond loopback every route of the page needs the
    access token (``token_file``, or a random one printed at start, when this page starts the
    server; else the console's).

    A lost console: the page polls its state every 0.2 s; when a path the operator set moving
    from this page (play, back, resume, seek) is still moving and that browser's page has not
    polled for ``lost_after`` seconds (closed, crashed, or its network lost), the module sends
    ``vcr pause`` itself: the player stops smoothly on the path and waits for a new play.
    """

    TYPE = "SketchPage"

    class Params(Parameters):
        host: str = param("", "web server host (empty: the console's, or 127.0.0.1)")
        port: int = param(0, "web server port (0: the console's, or a free one)", ge=0, le=65535)
        token_file: str = param(
            "", "file whose first line is the access token (when this page starts the server)"
        )
        jpeg_quality: int = param(85, "snapshot images", ge=30, le=100)
        lost_after: float = param(
            2.0, "a page that has not polled for this long has left", unit="s", gt=0
        )

    snapshot = Input(StereoSnapshot, required=False, doc="snapshots (Sketch)")
    primitive = Input(SketchPrimitive, required=False, doc="placed primitives (Sketch)")
    plan_preview = Input(ToolPath, required=False, doc="plans, passed or refused (Sketch)")
    vcr_state = Input(VcrState, required=False, feedback=True, doc="the player's state")
    sketch_status = Input(Status, required=False, doc="Sketch's reply to each command")
    command = Output(Text, events=True, doc="the page's commands (to Sketch.console)")

    def start(self) -> None:
        p = self.params
        token = resolve_token(p.token_file, self.name)
        self._server = acquire_server(self.context, p.host or None, p.port or None, token)
        self._control = self._server.control  # shared with the console of this server
        self._state: Latest[dict[str, Any]] = Latest()
        self._control_view: Latest[dict[str, Any]] = Latest()
        self._images: Latest[tuple[str, bytes, bytes]] = Latest()
        #: the snapshot's stereo pair and image b's size, for epipolar curves (web thread)
        self._pair: Latest[tuple[str, StereoPair, tuple[int, int]]] = Latest()
        #: requests by browser: the holder's never wait behind another browser's
        self._inbox: Lanes[_Request] = Lanes(per_session=4, budget=16, holder_capacity=64)
        self._primitives: list[SketchPrimitive] = []
        self._vcr_key: tuple | None = None
        self._control_key: tuple | None = None
        self._sent = 0
        self._refused = 0  #: malformed requests (web thread)
        self._control_refused = 0  #: requests refused for want of control (step)
        #: viewer key -> (monotonic time of its page's last poll or request, its address);
        #: written by the web thread, read by ``step``
        self._seen: dict[str, tuple[float, str]] = {}
        self._seen_lock = threading.Lock()
        self._malformed_log = Refusals()  #: logs malformed requests at most once a second
        self._sessions: dict[str, str] = {}  #: viewer key -> session in the control table
        self._numbers = itertools.count(1)
        self._driver: str | None = None  #: viewer whose VCR command set the path moving
        self._lost = 0
        self._now = 0.0  #: the current step's time [s]
        app = self._server.app
        app.add_api_route("/sketch", self._page, methods=["GET"])
        app.add_api_route("/sketch/sketch.js", self._script, methods=["GET"])
        app.add_api_route("/sketch/state", self._get_state, methods=["GET"])
        app.add_api_route("/sketch/image/{side}", self._image, methods=["GET"])
        app.add_api_route("/sketch/epipolar", self._epipolar, methods=["GET"])
        app.add_api_route("/sketch/command", self._post_command, methods=["POST"])
        app.add_api_route("/sketch/control", self._post_control, methods=["POST"])
        self._server.add_link("/sketch", "Active Sketch")
        self.log.info("Active Sketch page: %s", self.url)

    @property
    def url(self) -> str:
        """The page's address (with the access token when the server has one)."""
        root, _, query = self._server.url.partition("?")
        return root.rstrip("/") + "/sketch" + (f"?{query}" if query else "")

    def _command_origin(self) -> float:
        """The origin [s] of a command from the page: the snapshot the operator acts on, else
        the step's time (an intent, no sensor data). Not the oldest of every input the step
        read: in a process of its own the page may hold a sample that came before its clock
        was matched to its producer's, undatable for good, which would make every command,
        and the path planned from it, undatable too (the player refuses such a path)."""
        snap = self.snapshot.value
        if snap is not None and math.isfinite(snap.origin) and snap.origin > 0:
            return snap.origin
        return self._now

    def step(self, now: float) -> None:
        self._now = now
        changed = False
        snap = self.snapshot.get(now)
        if snap is not None and self.snapshot.fresh:
            quality = [cv2.IMWRITE_JPEG_QUALITY, self.params.jpeg_quality]
            a = cv2.imencode(".jpg", snap.image_a, quality)[1].tobytes()
            b = cv2.imencode(".jpg", snap.image_b, quality)[1].tobytes()
            self._images.put((snap.snapshot_id, a, b))
            size_b = (int(snap.image_b.shape[1]), int(snap.image_b.shape[0]))
            self._pair.put((snap.snapshot_id, StereoPair.from_snapshot(snap), size_b))
            changed = True
        prim = self.primitive.get(now)
        if prim is not None and self.primitive.fresh:
            self._primitives.append(prim)
            changed = True
        for port in (self.plan_preview, self.sketch_status):
            if port.get(now) is not None and port.fresh:
                changed = True
        vcr = self.vcr_state.get(now)
        if vcr is not None:
            key = (vcr.path_id, vcr.mode, round(vcr.progress, 3), vcr.speed, vcr.reason)
            changed |= key != self._vcr_key
            self._vcr_key = key
        if changed:
            self._state.put(
                page_state(
                    self.snapshot.get(now),
                    self._primitives,
                    self.plan_preview.get(now),
                    self.vcr_state.get(now),
                    self.sketch_status.get(now),
                )
            )
        wall = time.monotonic()
        seen = self._sync_sessions(wall)
        for request in self._inbox.drain():
            if request.reply.set_running_or_notify_cancel():  # else the web side gave up
                request.reply.set_result(self._decide(request, wall))
        holder = self._control.holder_browser()
        self._inbox.set_holders(frozenset((holder,)) if holder else frozenset())
        self._publish_control()
        self._watch_page(vcr, seen, wall)

    # -- control (step) -----------------------------------------------------------------------
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

    def _decide(self, request: _Request, wall: float) -> Decision:
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
            self._driver = request.viewer if cmd.action in _MOVING else None
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

    def stop(self) -> None:
        for session in self._sessions.values():
            self._control.leave(session)
        self._sessions.clear()
        release_server(self._server)

    # -- web thread ---------------------------------------------------------------------------
    def _saw(self, request: Request) -> str:
        """The request's viewer key ("" none); its browser's page is alive."""
        viewer = str(request.scope.get(VIEWER_SCOPE, ""))
        if viewer:
            host = request.client.host if request.client else "?"
            with self._seen_lock:
                if viewer not in self._seen and len(self._seen) >= MAX_PAGE_CONNECTIONS:
                    return ""  # as many browsers as the server has connections: no more
                self._seen[viewer] = (time.monotonic(), host)
        return viewer

    async def _page(self) -> HTMLResponse:
        return HTMLResponse(_static("sketch.html"), headers={"cache-control": "no-store"})

    async def _script(self) -> Response:
        return Response(_static("sketch.js"), media_type="text/javascript")

    async def _get_state(self, request: Request) -> JSONResponse:
        viewer = self._saw(request)
        version, state = self._state.get()
        _, control = self._control_view.get()
        control = control or {}
        mine = bool(viewer) and viewer == control.get("holder_browser")
        return JSONResponse(
            {
                "version": version,
                **(state or {}),
                "control": {
                    "holder": control.get("holder", ""),
                    "mine": mine,
                    "you": control.get("names", {}).get(viewer, ""),
                    "refused": control.get("refused", 0),
                },
            }
        )

    async def _image(self, side: str) -> Response:
        _, images = self._images.get()
        if images is None or side not in ("a.jpg", "b.jpg"):
            return Response(status_code=404)
        return Response(
            images[1] if side == "a.jpg" else images[2],
            media_type="image/jpeg",
            headers={"Cache-Control": "no-store"},
        )

    async def _epipolar(self, request: Request) -> JSONResponse:
        """``?u=U&v=V`` (px, image a): the epipolar curve in image b, as the camera model gives
        it (``StereoPair.epipolar_curve_b``), for the page to draw and to keep b's vertex on."""
        try:
            pixel = [float(request.query_params[k]) for k in ("u", "v")]
        except (KeyError, ValueError):
            return self._malformed("/sketch/epipolar: expected ?u=U&v=V, numbers in pixels")
        if not all(math.isfinite(x) and abs(x) < 1e6 for x in pixel):
            return self._malformed(f"/sketch/epipolar: expected finite pixels, got {pixel}")
        _, held = self._pair.get()
        if held is None:
            return JSONResponse({"snapshot": None, "points": []})
        sid, pair, size_b = held
        points = await asyncio.to_thread(pair.epipolar_curve_b, pixel, size_b)
        return JSONResponse({"snapshot": sid, "points": points.tolist()})

    def _malformed(self, message: str) -> JSONResponse:
        self._refused += 1
        self._malformed_log.add("malformed", f"a malformed request to {self.name}: {message}")
        return JSONResponse({"ok": False, "error": message}, status_code=400)

    async def _post_command(self, request: Request) -> JSONResponse:
        viewer = self._saw(request)
        body = await request.body()
        try:
            text = str(json.loads(body[: MAX_COMMAND_CHARS + 100])["text"])
            if len(text) > MAX_COMMAND_CHARS:
                raise ValueError(f"at most {MAX_COMMAND_CHARS} characters")
            parse(text)
        except Exception as exc:  # any malformed request is refused with the reason
            return self._malformed(f'expected {{"text": COMMAND}}: {exc}')
        return await self._ask(request, viewer, "command", text)

    async def _post_control(self, request: Request) -> JSONResponse:
        viewer = self._saw(request)
        body = await request.body()
        try:
            action = str(json.loads(body[:200])["action"])
            if action not in ("take", "release"):
                raise ValueError(f"found {action!r}")
        except Exception as exc:  # any malformed request is refused with the reason
            return self._malformed(f'expected {{"action": "take" or "release"}}: {exc}')
        return await self._ask(request, viewer, action, "")

    async def _ask(self, request: Request, viewer: str, kind: str, text: str) -> JSONResponse:
        """Queue the request for ``step`` and answer with its decision."""
        host = request.client.host if request.client else "?"
        reply: concurrent.futures.Future = concurrent.futures.Future()
        if not self._inbox.put(viewer, _Request(viewer, host, kind, text, reply)):
            return JSONResponse(
                {"ok": False, "error": "refused: too many of your requests are waiting"}, 429
            )
        try:
            decision = await asyncio.wait_for(asyncio.wrap_future(reply), REPLY_TIMEOUT_S)
        except TimeoutError:  # cancelled: step drops it, it is never sent late
            return JSONResponse(
                {
                    "ok": False,
                    "error": f"refused: the page's module did not answer within "
                    f"{REPLY_TIMEOUT_S:.0f} s (is the run stopping?)",
                },
                status_code=503,
            )
        if decision.ok:
            return JSONResponse({"ok": True, "message": decision.message})
        return JSONResponse({"ok": False, "error": decision.message}, status_code=403)

    def summary(self) -> dict[str, int]:
        return {
            "commands_sent": self._sent,
            "commands_refused": self._refused + self._control_refused,
            "malformed": self._refused,
            "control_refused": self._control_refused,
            "paused_for_lost_page": self._lost,
        }
