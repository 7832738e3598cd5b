"""SketchPage: the Active Sketch page, /sketch on the umbra process's web server."""

from __future__ import annotations

import asyncio
import collections
import itertools
import math
import threading
import time
from typing import Any

import cv2

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.access.secret import resolve_token
from umbra.connectors.messages import Image, Status, Text
from umbra.modules.operator.mailbox import Lanes, Latest
from umbra.modules.operator.web_server import acquire_server, release_server
from umbra.modules.sketch.messages import SketchPrimitive, StereoSnapshot, ToolPath, VcrState
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.sketch_page.page_control import PageControl
from umbra.modules.sketch_page.page_state import page_state
from umbra.modules.sketch_page.page_web import PageRequest, PageWeb
from umbra.modules.webdoor.gate import Refusals


class SketchPage(PageControl, PageWeb, Module):
    """The operator's Active Sketch page on the console's web server (``/sketch``).

    Shows the last snapshot pair side by side with SVG overlays: primitives dropped in both
    images, vertices dragged (the right-hand ones ride on their epipolar lines), reprojected
    3-D vertices, the macro menu, the planned path, the VCR buttons and speed. The page's
    actions come back as Sketch text commands (``modules/sketch/command_text.py``), checked here
    before they are queued; the module sends them on ``command`` (wire it to Sketch.console).
    The web side never touches the graph: it reads the latest messages through
    :class:`~umbra.modules.operator.mailbox.Latest` and queues requests in
    :class:`~umbra.modules.operator.mailbox.Lanes` (one per browser; the holder's first) that
    ``step`` drains and answers.

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
    verdict = Input(
        Status,
        required=False,
        doc="each macro's verdict, success or miss with the numbers (SketchWorld.verdict)",
    )
    live_a = Input(
        Image, required=False, doc="camera a's live frames (as the PTU slews it to watch)"
    )
    live_b = Input(Image, required=False, doc="camera b's live frames")
    command = Output(Text, events=True, doc="the page's commands (to Sketch.console)")

    def start(self) -> None:
        p = self.params
        token = resolve_token(p.token_file, self.name)
        self._server = acquire_server(self.context, p.host or None, p.port or None, token)
        self._control = self._server.control  # shared with the console of this server
        self._state: Latest[dict[str, Any]] = Latest()
        self._control_view: Latest[dict[str, Any]] = Latest()
        self._images: Latest[tuple[str, bytes, bytes]] = Latest()
        self._live: dict[str, Latest[Image]] = {"a": Latest(), "b": Latest()}
        #: per live camera: (frame version, JPEG, stamp) of the last encoding, for every poll of
        #: that frame (web thread), and the encodings counted
        self._live_jpeg: dict[str, tuple[int, bytes, float]] = {}
        self._live_locks: dict[str, asyncio.Lock] = {}
        self.live_encodes: collections.Counter[str] = collections.Counter()
        #: the snapshot's stereo pair and image b's size, for epipolar curves (web thread)
        self._pair: Latest[tuple[str, StereoPair, tuple[int, int]]] = Latest()
        #: requests by browser: the holder's never wait behind another browser's
        self._inbox: Lanes[PageRequest] = Lanes(per_session=4, budget=16, holder_capacity=64)
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
        app.add_api_route("/sketch/live/{side}", self._live_image, methods=["GET"])
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
        for port in (self.plan_preview, self.sketch_status, self.verdict):
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
                    self.verdict.get(now),
                )
            )
        for side, port in (("a", self.live_a), ("b", self.live_b)):
            frame = port.get(now)
            if frame is not None and port.fresh:
                self._live[side].put(frame)  # encoded only when a page asks (web thread)
        wall = time.monotonic()
        seen = self._sync_sessions(wall)
        for request in self._inbox.drain():
            if request.reply.set_running_or_notify_cancel():  # else the web side gave up
                request.reply.set_result(self._decide(request, wall))
        holder = self._control.holder_browser()
        self._inbox.set_holders(frozenset((holder,)) if holder else frozenset())
        self._publish_control()
        self._watch_page(vcr, seen, wall)

    def stop(self) -> None:
        for session in self._sessions.values():
            self._control.leave(session)
        self._sessions.clear()
        release_server(self._server)

    def summary(self) -> dict[str, int]:
        return {
            "commands_sent": self._sent,
            "commands_refused": self._refused + self._control_refused,
            "malformed": self._refused,
            "control_refused": self._control_refused,
            "paused_for_lost_page": self._lost,
        }
