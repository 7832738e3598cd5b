"""SketchPage: the Active Sketch page, /sketch on the umbra process's web server."""

from __future__ import annotations

import json
from importlib import resources
from typing import Any

import cv2
from fastapi import Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from connectors import Input, Module, Output, Parameters, param
from connectors.messages import Status, Text
from connectors.sketch_messages import SketchPrimitive, StereoSnapshot, ToolPath, VcrState
from modules.operator.mailbox import Inbox, Latest
from modules.operator.web_server import acquire_server, release_server
from modules.sketch.command_text import parse
from modules.sketch_page.page_state import page_state

MAX_COMMAND_CHARS = 2000


def _static(name: str) -> str:
    return resources.files("modules.sketch_page").joinpath("static", name).read_text("utf-8")


class SketchPage(Module):
    """The operator's Active Sketch page on the console's web server (``/sketch``).

    Shows the last snapshot pair side by side with SVG overlays: primitives dropped in both
    images, vertices dragged (the right-hand ones ride on their epipolar lines), reprojected
    3-D vertices, the macro menu, the planned path, the VCR buttons and speed. The page's
    actions come back as Sketch text commands (``modules/sketch/command_text.py``), checked here
    before they are queued; the module sends them on ``command`` (wire it to Sketch.console).
    The web side never touches the graph: it reads the latest messages through
    :class:`~modules.operator.mailbox.Latest` and queues commands in an
    :class:`~modules.operator.mailbox.Inbox` that ``step`` drains.
    """

    TYPE = "SketchPage"

    class Params(Parameters):
        host: str = param("", "web server host (empty: the console's, or 127.0.0.1)")
        port: int = param(0, "web server port (0: the console's, or a free one)", ge=0, le=65535)
        jpeg_quality: int = param(85, "snapshot images", ge=30, le=100)

    snapshot = Input(StereoSnapshot, required=False, doc="snapshots (Sketch)")
    primitive = Input(SketchPrimitive, required=False, doc="placed primitives (Sketch)")
    plan_preview = Input(ToolPath, required=False, doc="plans, passed or refused (Sketch)")
    vcr_state = Input(VcrState, required=False, feedback=True, doc="the player's state")
    sketch_status = Input(Status, required=False, doc="Sketch's reply to each command")
    command = Output(Text, doc="the page's commands (to Sketch.console)")

    def start(self) -> None:
        p = self.params
        self._server = acquire_server(self.context, p.host or None, p.port or None)
        self._state: Latest[dict[str, Any]] = Latest()
        self._images: Latest[tuple[str, bytes, bytes]] = Latest()
        self._inbox: Inbox[str] = Inbox(capacity=64)
        self._primitives: list[SketchPrimitive] = []
        self._vcr_key: tuple | None = None
        self._sent = 0
        self._refused = 0
        app = self._server.app
        app.add_api_route("/sketch", self._page, methods=["GET"])
        app.add_api_route("/sketch/sketch.js", self._script, methods=["GET"])
        app.add_api_route("/sketch/state", self._get_state, methods=["GET"])
        app.add_api_route("/sketch/image/{side}", self._image, methods=["GET"])
        app.add_api_route("/sketch/command", self._post_command, methods=["POST"])
        self._server.add_link("/sketch", "Active Sketch")
        self.log.info(
            "Active Sketch page: http://%s:%d/sketch", self._server.host, self._server.port
        )

    @property
    def url(self) -> str:
        return f"http://{self._server.host}:{self._server.port}/sketch"

    def step(self, now: float) -> None:
        changed = False
        snap = self.snapshot.get(now)
        if snap is not None and self.snapshot.fresh:
            quality = [cv2.IMWRITE_JPEG_QUALITY, self.params.jpeg_quality]
            a = cv2.imencode(".jpg", snap.image_a, quality)[1].tobytes()
            b = cv2.imencode(".jpg", snap.image_b, quality)[1].tobytes()
            self._images.put((snap.snapshot_id, a, b))
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
        for text in self._inbox.drain():
            self.command.send(Text(text=text))
            self._sent += 1

    def stop(self) -> None:
        release_server(self._server)

    # -- web thread ---------------------------------------------------------------------------
    async def _page(self) -> HTMLResponse:
        return HTMLResponse(_static("sketch.html"))

    async def _script(self) -> Response:
        return Response(_static("sketch.js"), media_type="text/javascript")

    async def _get_state(self) -> JSONResponse:
        version, state = self._state.get()
        return JSONResponse({"version": version, **(state or {})})

    async def _image(self, side: str) -> Response:
        _, images = self._images.get()
        if images is None or side not in ("a.jpg", "b.jpg"):
            return Response(status_code=404)
        return Response(
            images[1] if side == "a.jpg" else images[2],
            media_type="image/jpeg",
            headers={"Cache-Control": "no-store"},
        )

    async def _post_command(self, request: Request) -> JSONResponse:
        body = await request.body()
        try:
            text = str(json.loads(body[: MAX_COMMAND_CHARS + 100])["text"])
            if len(text) > MAX_COMMAND_CHARS:
                raise ValueError(f"at most {MAX_COMMAND_CHARS} characters")
            parse(text)
        except Exception as exc:  # any malformed request is refused with the reason
            self._refused += 1
            return JSONResponse(
                {"ok": False, "error": f'expected {{"text": COMMAND}}: {exc}'}, status_code=400
            )
        if not self._inbox.put(text):
            return JSONResponse({"ok": False, "error": "too many commands queued"}, 429)
        return JSONResponse({"ok": True})

    def summary(self) -> dict[str, int]:
        return {"commands_sent": self._sent, "commands_refused": self._refused}
