"""The /sketch page's web side: its routes run on the web server's thread, read the latest
state through :class:`~umbra.modules.operator.mailbox.Latest` and queue requests for ``step`` (a
part that :class:`~umbra.modules.sketch_page.sketch_page.SketchPage` owns); they never touch the
graph.
"""

from __future__ import annotations

import asyncio
import collections
import concurrent.futures
import json
import math
import threading
import time
from dataclasses import dataclass
from importlib import resources
from typing import Any

import cv2
from fastapi import FastAPI, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from umbra.connectors.limits import MAX_PAGE_CONNECTIONS
from umbra.connectors.messages import Image
from umbra.modules.operator.control import Decision
from umbra.modules.operator.mailbox import Lanes, Latest
from umbra.modules.sketch.command_text import parse
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.webdoor.gate import Refusals
from umbra.modules.webdoor.viewer import VIEWER_SCOPE

MAX_COMMAND_CHARS = 2000
#: the web side waits at most this long for ``step`` to decide on a request [s]
REPLY_TIMEOUT_S = 5.0


def static_text(name: str) -> str:
    """A file of the page (``static/NAME``), served from the package."""
    return (
        resources.files("umbra.modules.sketch_page")
        .joinpath("static")
        .joinpath(name)
        .read_text("utf-8")
    )


@dataclass(frozen=True)
class PageRequest:
    """From the web thread to ``step``: a checked command (``kind`` "command", its ``text``)
    or a control request ("take" / "release"), the browser it came from (viewer key, "" none)
    and its address, and where ``step`` puts its :class:`Decision`."""

    viewer: str
    host: str
    kind: str
    text: str
    reply: concurrent.futures.Future[Decision]


class PageWeb:
    """The routes of the /sketch page (web thread) and what they share with ``step``: the latest
    page state, control view, snapshot images, live frames and stereo pair (``step`` puts, the
    routes get), the requests' lanes (the routes put, ``step`` drains), the browsers seen (under
    ``seen_lock``) and the malformed requests counted."""

    def __init__(self, name: str, jpeg_quality: int) -> None:
        self._name = name  #: the module's, in the log
        self._jpeg_quality = jpeg_quality
        self.state: Latest[dict[str, Any]] = Latest()
        self.control_view: Latest[dict[str, Any]] = Latest()
        self.images: Latest[tuple[str, bytes, bytes]] = Latest()
        self.live: dict[str, Latest[Image]] = {"a": Latest(), "b": Latest()}
        #: per live camera: (frame version, JPEG, stamp) of the last encoding, for every poll of
        #: that frame (web thread), and the encodings counted
        self._live_jpeg: dict[str, tuple[int, bytes, float]] = {}
        self._live_locks: dict[str, asyncio.Lock] = {}
        self.live_encodes: collections.Counter[str] = collections.Counter()
        #: the snapshot's stereo pair and image b's size, for epipolar curves (web thread)
        self.pair: Latest[tuple[str, StereoPair, tuple[int, int]]] = Latest()
        #: requests by browser: the holder's never wait behind another browser's
        self.inbox: Lanes[PageRequest] = Lanes(per_session=4, budget=16, holder_capacity=64)
        self.refused = 0  #: malformed requests (web thread)
        #: viewer key -> (monotonic time of its page's last poll or request, its address);
        #: written by the web thread, read by ``step``
        self.seen: dict[str, tuple[float, str]] = {}
        self.seen_lock = threading.Lock()
        self._malformed_log = Refusals()  #: logs malformed requests at most once a second

    def add_routes(self, app: FastAPI) -> None:
        """Serve the page's routes on ``app``."""
        app.add_api_route("/sketch", self._page, methods=["GET"])
        app.add_api_route("/sketch/sketch.js", self._script, methods=["GET"])
        app.add_api_route("/sketch/state", self._get_state, methods=["GET"])
        app.add_api_route("/sketch/image/{side}", self._image, methods=["GET"])
        app.add_api_route("/sketch/live/{side}", self._live_image, methods=["GET"])
        app.add_api_route("/sketch/epipolar", self._epipolar, methods=["GET"])
        app.add_api_route("/sketch/command", self._post_command, methods=["POST"])
        app.add_api_route("/sketch/control", self._post_control, methods=["POST"])

    def _saw(self, request: Request) -> str:
        """The request's viewer key ("" none); its browser's page is alive."""
        viewer = str(request.scope.get(VIEWER_SCOPE, ""))
        if viewer:
            host = request.client.host if request.client else "?"
            with self.seen_lock:
                if viewer not in self.seen and len(self.seen) >= MAX_PAGE_CONNECTIONS:
                    return ""  # as many browsers as the server has connections: no more
                self.seen[viewer] = (time.monotonic(), host)
        return viewer

    async def _page(self) -> HTMLResponse:
        return HTMLResponse(static_text("sketch.html"), headers={"cache-control": "no-store"})

    async def _script(self) -> Response:
        return Response(static_text("sketch.js"), media_type="text/javascript")

    async def _get_state(self, request: Request) -> JSONResponse:
        viewer = self._saw(request)
        version, state = self.state.get()
        _, control = self.control_view.get()
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
        _, images = self.images.get()
        if images is None or side not in ("a.jpg", "b.jpg"):
            return Response(status_code=404)
        return Response(
            images[1] if side == "a.jpg" else images[2],
            media_type="image/jpeg",
            headers={"Cache-Control": "no-store"},
        )

    async def _live_image(self, side: str) -> Response:
        """``a.jpg`` / ``b.jpg``: the camera's latest live frame, encoded when a page first asks
        for it (nothing is encoded while no page watches) and once per frame however many
        polls ask (``live_encodes`` counts the encodings); 404 before the first frame."""
        name = side.removesuffix(".jpg") if side.endswith(".jpg") else ""
        live = self.live.get(name)
        if live is None or live.get()[1] is None:
            return Response(status_code=404)
        lock = self._live_locks.setdefault(name, asyncio.Lock())  # (one web loop: no race)
        async with lock:  # a second poll of the same frame waits for the first's encoding
            version, frame = live.get()
            if frame is None:  # (not after the check above: a Latest keeps its newest)
                return Response(status_code=404)
            cached = self._live_jpeg.get(name)
            if cached is None or cached[0] != version:
                quality = [cv2.IMWRITE_JPEG_QUALITY, self._jpeg_quality]
                ok, jpeg = await asyncio.to_thread(cv2.imencode, ".jpg", frame.pixels, quality)
                if not ok:
                    return Response(status_code=500)
                self.live_encodes[name] += 1
                cached = self._live_jpeg[name] = (version, jpeg.tobytes(), frame.stamp)
        return Response(
            cached[1],
            media_type="image/jpeg",
            headers={"Cache-Control": "no-store", "X-Frame-Stamp": f"{cached[2]:.6f}"},
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
        _, held = self.pair.get()
        if held is None:
            return JSONResponse({"snapshot": None, "points": []})
        sid, pair, size_b = held
        points = await asyncio.to_thread(pair.epipolar_curve_b, pixel, size_b)
        return JSONResponse({"snapshot": sid, "points": points.tolist()})

    def _malformed(self, message: str) -> JSONResponse:
        self.refused += 1
        self._malformed_log.add("malformed", f"a malformed request to {self._name}: {message}")
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
        reply: concurrent.futures.Future[Decision] = concurrent.futures.Future()
        if not self.inbox.put(viewer, PageRequest(viewer, host, kind, text, reply)):
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
