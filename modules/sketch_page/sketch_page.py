"""SketchPage: the Active Sketch page, /sketch on the umbra process's web server."""

from __future__ import annotations

import math
import time

import cv2

from umbra.connectors import Input, Module, Output, Parameters, param
from umbra.connectors.access.hosts import MAX_TCP_PORT
from umbra.connectors.access.secret import resolve_token
from umbra.connectors.messages import Image, Status, Text, ZoomState
from umbra.connectors.path_messages import ToolPath, VcrState
from umbra.connectors.ptu_messages import PtuState
from umbra.connectors.sketch_messages import SketchPrimitive, StereoSnapshot
from umbra.connectors.states import Verdict
from umbra.modules.operator.web_server import acquire_server, release_server
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.sketch_page.camera_view import camera_view
from umbra.modules.sketch_page.page_control import PageControl
from umbra.modules.sketch_page.page_state import page_state
from umbra.modules.sketch_page.page_web import PageWeb


class SketchPage(Module["SketchPage.Params"]):
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
    (control held only there is free again). Every route of the page needs the access token, on
    loopback too (``token_file``, or a random one printed at start, when this page starts the
    server; else the console's).

    A lost console: the page polls its state every 0.2 s; when a path the operator set moving
    from this page (play, back, resume, seek) is still moving and that browser's page has not
    polled for ``lost_after`` seconds (closed, crashed, or its network lost), the module sends
    ``vcr pause`` itself: the player stops smoothly on the path and waits for a new play.
    """

    TYPE = "SketchPage"

    class Params(Parameters):
        host: str = param("", "web server host (empty: the console's, or 127.0.0.1)")
        port: int = param(
            0, "web server port (0: the console's, or a free one)", ge=0, le=MAX_TCP_PORT
        )
        token_file: str = param(
            "", "file whose first line is the access token (when this page starts the server)"
        )
        jpeg_quality: int = param(85, "snapshot images", ge=30, le=100)
        lost_after: float = param(
            2.0, "a page that has not polled for this long has left", unit="s", gt=0
        )
        device_silent_s: float = param(
            1.0,
            "a PTU or zoom camera that has not reported for this long is shown as silent",
            unit="s",
            gt=0,
        )

    snapshot = Input(StereoSnapshot, required=False, doc="snapshots (Sketch)")
    primitive = Input(SketchPrimitive, required=False, doc="placed primitives (Sketch)")
    plan_preview = Input(ToolPath, required=False, doc="plans, passed or refused (Sketch)")
    vcr_state = Input(VcrState, required=False, feedback=True, doc="the player's state")
    sketch_status = Input(Status, required=False, doc="Sketch's reply to each command")
    verdict = Input(
        Verdict,
        required=False,
        doc="each macro's verdict, success or miss with the numbers (SketchWorld.verdict)",
    )
    live_a = Input(
        Image, required=False, doc="camera a's live frames (as the PTU slews it to watch)"
    )
    live_b = Input(Image, required=False, doc="camera b's live frames")
    ptu_a = Input(PtuState, required=False, doc="camera a's pan/tilt unit: moving, angles")
    ptu_b = Input(PtuState, required=False, doc="camera b's pan/tilt unit: moving, angles")
    zoom_a = Input(ZoomState, required=False, doc="camera a's zoom (SONY.zoom)")
    zoom_b = Input(ZoomState, required=False, doc="camera b's zoom (SONY.zoom)")
    command = Output(Text, events=True, doc="the page's commands (to Sketch.console)")

    def start(self) -> None:
        p = self.params
        token = resolve_token(p.token_file, self.name)
        self._server = acquire_server(self.context, p.host or None, p.port or None, token)
        self._control = self._server.control  # shared with the console of this server
        self.web = PageWeb(self.name, p.jpeg_quality)  #: the routes (web thread)
        self.page_control = PageControl(self, self.web)  #: control and commands (step)
        self._primitives: list[SketchPrimitive] = []
        self._vcr_key: tuple[str, str, float, float, str] | None = None
        self._cameras: list[dict[str, object]] = []  #: the devices as the page last showed them
        self._now = 0.0  #: the current step's time [s]
        self.web.add_routes(self._server.app)
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
        snap: StereoSnapshot | None = self.snapshot.value
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
            self.web.images.put((snap.snapshot_id, a, b))
            size_b = (int(snap.image_b.shape[1]), int(snap.image_b.shape[0]))
            self.web.pair.put((snap.snapshot_id, StereoPair.from_snapshot(snap), size_b))
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
        cameras = self._camera_views(now)
        changed |= cameras != self._cameras
        self._cameras = cameras
        if changed:
            self.web.state.put(
                page_state(
                    self.snapshot.get(now),
                    self._primitives,
                    self.plan_preview.get(now),
                    self.vcr_state.get(now),
                    self.sketch_status.get(now),
                    self.verdict.get(now),
                    cameras,
                )
            )
        for side, port in (("a", self.live_a), ("b", self.live_b)):
            frame = port.get(now)
            if frame is not None and port.fresh:
                self.web.live[side].put(frame)  # encoded only when a page asks (web thread)
        wall = time.monotonic()
        control = self.page_control
        seen = control.sync_sessions(wall)
        for request in self.web.inbox.drain():
            if request.reply.set_running_or_notify_cancel():  # else the web side gave up
                request.reply.set_result(control.decide(request, wall))
        holder = self._control.holder_browser()
        self.web.inbox.set_holders(frozenset((holder,)) if holder else frozenset())
        control.publish_control()
        control.watch_page(vcr, seen, wall)

    def _camera_views(self, now: float) -> list[dict[str, object]]:
        """Each camera's PTU and zoom as the page shows them (:func:`camera_view`)."""
        silent = self.params.device_silent_s
        return [
            camera_view(side, ptu.get(now), ptu.age(now), zoom.get(now), zoom.age(now), silent)
            for side, ptu, zoom in (("a", self.ptu_a, self.zoom_a), ("b", self.ptu_b, self.zoom_b))
        ]

    def stop(self) -> None:
        self.page_control.leave_all()
        release_server(self._server)

    def summary(self) -> dict[str, int]:
        control, malformed = self.page_control, self.web.refused
        return {
            "commands_sent": control.sent,
            "commands_refused": malformed + control.control_refused,
            "malformed": malformed,
            "control_refused": control.control_refused,
            "paused_for_lost_page": control.lost,
        }
