"""The console's web side: its page, its websocket, and the frame pump (runs in the web thread).

Nothing here touches the graph: the module hands over frames and a state snapshot through
:class:`~umbra.modules.operator.mailbox.Latest`, and takes back checked messages through
:class:`~umbra.modules.operator.mailbox.Lanes` that its ``step`` drains: a page's arrival and
departure and the holder's commands never wait behind anything another page sends.

Each socket has a message budget (:class:`~umbra.connectors.access.rate.MessageBudget`): beyond its
rate, its burst or its malformed messages it is closed (1008, with the reason); a message larger
than
:data:`~umbra.connectors.limits.MAX_PAGE_MESSAGE_BYTES` is refused by the websocket protocol itself
(1009) before it is read whole. Malformed messages are answered on their socket and counted,
never queued for ``step``.

Video: each new camera image is JPEG-encoded once (in one encoder thread, only while a page
watches) and sent as a binary websocket message ``[4-byte header length][JSON header][JPEG]``.
A page has at most ``limits.MAX_PAGE_IN_FLIGHT`` frames and as many states sent and not yet
reported shown, so neither queues: the latest wins (:mod:`umbra.modules.operator.page_flow`).
The run's last state is sent to every open page, which says it has shown it, before the
console's process ends; the socket is then closed cleanly.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import json
import logging
import secrets
import struct
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import cv2
import numpy as np
from fastapi import WebSocket, WebSocketDisconnect
from fastapi.responses import HTMLResponse, Response

from umbra.connectors.access.rate import MessageBudget
from umbra.connectors.json_text import json_text
from umbra.modules.operator.console_params import PAGE_SILENT_S
from umbra.modules.operator.mailbox import Lanes, Latest
from umbra.modules.operator.page_flow import PageFlow
from umbra.modules.operator.protocol import MessageChecker, ProtocolError, ReplayedMessage
from umbra.modules.operator.web_server import WebServer
from umbra.modules.webdoor.viewer import VIEWER_SCOPE

_LOG = logging.getLogger("umbra.operator")

#: the close code and reason of a socket whose page has shown the run's end
_ENDED = (1000, "run ended")


@dataclass(frozen=True)
class RawFrame:
    """A camera image handed over by ``step``: pixels (BGR), its ``seq``, and for latency the
    wall time of the hand-over [s since epoch] and its age on the run's clock then [s]."""

    pixels: np.ndarray
    seq: int
    handoff_wall: float
    age_at_handoff: float


@dataclass(frozen=True)
class Event:
    """From the web thread to ``step``: ``kind`` join / leave / msg, the session, a
    payload, the wall time it arrived (monotonic seconds), and the page's browser key
    (:func:`~umbra.modules.operator.access.viewer_key`; "" unknown)."""

    kind: str
    session: str
    payload: Any
    wall: float
    browser: str = ""


@dataclass
class WebStats:
    """Figures gathered in the web thread (read by the module's summary)."""

    frames_encoded: int = 0
    frames_sent: int = 0
    latency_ms: list[float] = field(default_factory=list)
    painted_wall: list[float] = field(default_factory=list)
    malformed: int = 0
    replayed: int = 0
    closed_abusers: int = 0  #: sockets closed over their message budget
    oversize: int = 0  #: sockets the protocol closed for a message past its size (1009)
    lane_full: int = 0  #: messages refused because their session's lane was full
    viewers: int = 0
    viewers_max: int = 0
    encoder_tid: int = 0
    web_tid: int = 0


#: the station's files by route (``/station/<name>``): its style, one small script per panel,
#: and the vendored plotting library (uPlot, MIT; see ``static/vendor/README.txt``)
_MEDIA = {".js": "text/javascript", ".css": "text/css"}


def _static(name: str) -> str:
    return (
        resources.files("umbra.modules.operator")
        .joinpath("static")
        .joinpath(name)
        .read_text("utf-8")
    )


def _station_files() -> dict[str, tuple[str, str]]:
    """``name -> (text, media type)`` of every file the station page loads (read once)."""
    root = resources.files("umbra.modules.operator").joinpath("static")
    files: dict[str, tuple[str, str]] = {"station.css": (_static("station.css"), "text/css")}
    for folder in ("panels", "vendor"):
        for entry in root.joinpath(folder).iterdir():
            media = _MEDIA.get("." + entry.name.rsplit(".", 1)[-1])
            if media is not None:
                files[f"{folder}/{entry.name}"] = (entry.read_text("utf-8"), media)
    return files


class ConsoleApp:
    """Routes of one console on a :class:`WebServer`, under ``prefix`` ("" for the root)."""

    def __init__(self, server: WebServer, lanes: Lanes[Event], jpeg_quality: int) -> None:
        self.server = server
        self.lanes = lanes
        self.frames: Latest[RawFrame] = Latest()
        self.state: Latest[dict[str, Any]] = Latest()
        self.assist_frame: Latest[np.ndarray] = Latest()
        self.stats = WebStats()
        self.jpeg_quality = jpeg_quality
        self._encoded: Latest[bytes] = Latest()
        self._state_json: tuple[int, str] = (0, "")
        self._encoder = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="umbra-jpeg")
        self._pump: asyncio.Task[None] | None = None
        self._names = itertools.count(1)
        self._lock = threading.Lock()
        self._page = _static("station.html")
        self._files = _station_files()
        #: per open socket: what is on its way to its page (web thread writes, ``flush_final``
        #: reads)
        self._flows: dict[int, PageFlow] = {}
        self._final_version = 0  #: the version of the run's last state (0: the run goes on)
        app = server.app
        app.add_api_route("/", self._index, methods=["GET"])
        app.add_api_route("/station/{folder}/{name}", self._file, methods=["GET"])
        app.add_api_route("/station/{name}", self._file, methods=["GET"])
        app.add_api_route("/assist.jpg", self._assist_jpeg, methods=["GET"])
        app.add_api_websocket_route("/ws", self._socket)

    raw_frame = RawFrame  #: what ``step`` hands over (here so the module imports no web code)

    def close(self) -> None:
        self._encoder.shutdown(wait=False, cancel_futures=True)

    # -- HTTP ------------------------------------------------------------------------------
    async def _index(self) -> HTMLResponse:
        return HTMLResponse(self._page, headers={"cache-control": "no-store"})

    async def _file(self, name: str, folder: str = "") -> Response:
        found = self._files.get(f"{folder}/{name}" if folder else name)
        if found is None:
            return Response(status_code=404)
        return Response(found[0], media_type=found[1], headers={"cache-control": "no-cache"})

    def flush_final(self, state: dict[str, Any], timeout: float) -> None:
        """Hand the pages their last state (the run's end) and wait, at most ``timeout`` [s],
        until every open page has shown it (a client that does not say what it showed: until
        it was sent). Called by the stopping module, not the web thread."""
        self.state.put(state)
        version = self._final_version = self.state.get()[0]
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if all(flow.final_done(version) for flow in list(self._flows.values())):
                return
            threading.Event().wait(0.02)

    async def _assist_jpeg(self) -> Response:
        _, pixels = self.assist_frame.get()
        if pixels is None:
            return Response(status_code=404)
        data = await asyncio.get_running_loop().run_in_executor(self._encoder, self._encode, pixels)
        return Response(data, media_type="image/jpeg", headers={"cache-control": "no-store"})

    def _encode(self, pixels: np.ndarray) -> bytes:
        if not self.stats.encoder_tid:
            self.stats.encoder_tid = threading.get_native_id()
        ok, buf = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if not ok:
            raise ValueError("JPEG encoding failed")
        return buf.tobytes()

    # -- frame pump ------------------------------------------------------------------------
    async def _pump_frames(self) -> None:
        """Encode each new frame once while anyone watches (latest wins)."""
        loop = asyncio.get_running_loop()
        version = 0
        while True:
            version, frame = await self.frames.wait_newer(version, 0.5)
            if frame is None or self.stats.viewers == 0:
                continue
            t0 = time.perf_counter()
            try:
                jpeg = await loop.run_in_executor(self._encoder, self._encode, frame.pixels)
            except RuntimeError:  # the encoder is shut: the run ended (its pages get no frames)
                return
            h, w = frame.pixels.shape[:2]
            header = json.dumps(
                {
                    "frame": frame.seq,
                    "w": int(w),
                    "h": int(h),
                    "handoff_wall_ms": frame.handoff_wall * 1e3,
                    "age_ms": frame.age_at_handoff * 1e3,
                    "encode_ms": (time.perf_counter() - t0) * 1e3,
                }
            ).encode()
            self.stats.frames_encoded += 1
            self._encoded.put(struct.pack(">I", len(header)) + header + jpeg)

    # -- websocket -------------------------------------------------------------------------
    async def _socket(self, ws: WebSocket) -> None:
        await ws.accept()
        if not self.stats.web_tid:
            self.stats.web_tid = threading.get_native_id()
        if self._pump is None:
            self._pump = asyncio.create_task(self._pump_frames())
        session = secrets.token_hex(8)
        client = ws.client
        name = f"viewer {next(self._names)} ({client.host if client else '?'})"
        checker = MessageChecker(session)
        budget = MessageBudget()
        flow = PageFlow()
        self.stats.viewers += 1
        self.stats.viewers_max = max(self.stats.viewers_max, self.stats.viewers)
        browser = ws.scope.get(VIEWER_SCOPE, "")
        self.lanes.joined(Event("join", session, name, time.monotonic(), browser))
        sender: asyncio.Task[None] | None = None
        try:
            welcome = {"type": "welcome", "session": session, "name": name}
            await ws.send_text(json.dumps({**welcome, "silent_s": PAGE_SILENT_S}))
            sender = asyncio.create_task(self._send_loop(ws, flow))
            while True:
                message = await ws.receive()
                if message["type"] == "websocket.disconnect":
                    self.stats.oversize += message.get("code") == 1009
                    break
                why = budget.spend(time.monotonic())
                if not why:
                    why = await self._one(ws, session, checker, budget, flow, message)
                if why:
                    self.stats.closed_abusers += 1
                    _LOG.warning("console: closed the socket of %s: %s", name, why)
                    await ws.close(1008, why[:120])
                    break
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass
        finally:
            if sender is not None:
                sender.cancel()
            self.stats.viewers -= 1
            self.lanes.left(session, Event("leave", session, None, time.monotonic()))

    async def _one(
        self,
        ws: WebSocket,
        session: str,
        checker: MessageChecker,
        budget: MessageBudget,
        flow: PageFlow,
        message: Mapping[str, Any],
    ) -> str:
        """Check one message and queue it for ``step``; "" or why the socket must close."""
        raw = message.get("text")
        if raw is None:
            raw = "<binary message: expected JSON text>"
        try:
            msg = checker.check(raw)
        except ProtocolError as exc:
            text = str(exc)
            if isinstance(exc, ReplayedMessage):
                self.stats.replayed += 1
            else:
                self.stats.malformed += 1
            why = budget.spoiled()
            if not why:
                await ws.send_text(json.dumps({"type": "notice", "level": "error", "text": text}))
            return why
        if msg.type == "painted":
            if msg.fields["latency_ms"] > 0:  # 0: overtaken by a newer frame, not drawn
                self._painted(msg.fields["latency_ms"])
            flow.frames.acknowledge()
            return ""
        if msg.type == "seen":
            flow.states.acknowledge(msg.fields["state"])
            return ""
        if not self.lanes.put(session, Event("msg", session, msg, time.monotonic())):
            self.stats.lane_full += 1
            await ws.send_text(
                json.dumps(
                    {
                        "type": "notice",
                        "level": "error",
                        "text": "refused: too many of your messages are waiting (slow down)",
                    }
                )
            )
        return ""

    def _painted(self, latency_ms: float) -> None:
        if len(self.stats.latency_ms) < 100_000:
            self.stats.latency_ms.append(float(latency_ms))
            self.stats.painted_wall.append(time.monotonic())

    def _state_text(self, version: int, state: dict[str, Any]) -> str:
        """The state as JSON, serialized once per version for every page."""
        cached = self._state_json
        if cached[0] != version:
            text = json_text({"type": "state", "version": version, **state})
            cached = self._state_json = (version, text)
        return cached[1]

    async def _send_loop(self, ws: WebSocket, flow: PageFlow) -> None:
        """Send the newest state and the newest frame whenever the page has room for them
        (:mod:`~umbra.modules.operator.page_flow`); close the socket cleanly once the page has
        shown the run's end."""
        frame_version = 0
        key = id(ws)
        self._flows[key] = flow
        try:
            while True:
                if self._final_version and flow.states.shown(self._final_version):
                    await ws.close(*_ENDED)  # nothing more to say: no reset loses a word
                    return
                state_version, state = self.state.get()
                newer = state_version > flow.states.newest_sent
                if state is not None and newer and flow.states.can_send():
                    flow.states.sent(state_version)
                    await ws.send_text(self._state_text(state_version, state))
                version, data = self._encoded.get()
                if data is not None and version > frame_version and flow.frames.can_send():
                    frame_version = version
                    flow.frames.sent(version)
                    await ws.send_bytes(data)
                    self.stats.frames_sent += 1
                    continue
                waits = [
                    asyncio.ensure_future(
                        self.state.wait_newer(flow.states.newest_sent, 0.25)
                        if flow.states.can_send()
                        else flow.states.event.wait()
                    ),
                    asyncio.ensure_future(
                        self._encoded.wait_newer(frame_version, 0.25)
                        if flow.frames.can_send()
                        else flow.frames.event.wait()
                    ),
                ]
                _, pending = await asyncio.wait(
                    waits, timeout=0.25, return_when=asyncio.FIRST_COMPLETED
                )
                for task in pending:
                    task.cancel()
        except (asyncio.CancelledError, WebSocketDisconnect, RuntimeError):
            return
        finally:
            self._flows.pop(key, None)
