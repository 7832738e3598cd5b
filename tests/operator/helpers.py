"""Shared test helpers: a synthetic camera image, a contour of a rectangle, a websocket client."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Protocol, TypeVar

import httpx
import numpy as np
from websockets.sync.client import ClientConnection, connect

from umbra.connectors.messages import Contour, Image
from umbra.modules.vision.contour_message import contour_message
from umbra.modules.vision.features import polygon_features
from umbra.runtime.harness import ModuleHarness


def image(width: int = 640, height: int = 480) -> Image:
    """A gray frame with a green patch at (300..380, 200..260)."""
    pixels = np.full((height, width, 3), 90, np.uint8)
    pixels[200:260, 300:380] = (60, 170, 30)
    return Image(pixels=pixels)


def rectangle_contour(status: str = "tracking", reason: str = "") -> Contour:
    """The patch outline as a 16-vertex polygon."""
    u = np.linspace(300, 380, 5)[:-1]
    v = np.linspace(200, 260, 5)[:-1]
    top = np.c_[u, np.full(4, 200.0)]
    right = np.c_[np.full(4, 380.0), v]
    bottom = np.c_[u[::-1] + 20, np.full(4, 260.0)]
    left = np.c_[np.full(4, 300.0), v[::-1] + 15]
    vertices = np.vstack([top, right, bottom, left])
    return contour_message(
        vertices, polygon_features(vertices), status, reason, 0.0, offending=[3, 4]
    )


def client(url: str) -> tuple[httpx.Client, str]:
    """An HTTP client that opened ``url`` (with its token) as a browser does: the server set the
    token's cookie and redirected to the address without it. Returns the client (it sends the
    page's own Origin, as a browser's page does on a POST) and the server's root address."""
    root = url.split("?")[0].split("/", 3)
    base = "/".join(root[:3])
    http = httpx.Client(timeout=10, follow_redirects=True, headers={"Origin": base})
    opened = http.get(url)
    assert opened.status_code == 200, opened.text
    assert "token=" not in str(opened.url) and http.cookies.get("umbra_token")
    return http, base


class Page:
    """A minimal page over the real websocket: sends checked messages, reads the replies."""

    def __init__(self, url: str, origin: str | None = None) -> None:
        base, _, query = url.partition("?")
        ws_url = (
            base.replace("http://", "ws://").rstrip("/") + "/ws" + (f"?{query}" if query else "")
        )
        headers = {"Origin": origin} if origin else None
        self.ws: ClientConnection = connect(ws_url, open_timeout=5, additional_headers=headers)
        welcome = self.welcome = self.recv_text("welcome")
        self.session = welcome["session"]
        self.name = welcome["name"]
        self.seq = 0

    def send(self, type_: str, **fields: Any) -> None:
        self.seq += 1
        self.ws.send(
            json.dumps({"session": self.session, "seq": self.seq, "type": type_, **fields})
        )

    def raw(self, text: str) -> None:
        self.ws.send(text)

    def recv_text(self, kind: str, timeout: float = 5.0) -> dict[str, Any]:
        """The next text message of ``kind`` (frames and others are skipped)."""
        import time

        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self.ws.recv(timeout=max(0.01, end - time.monotonic()))
            if isinstance(msg, str):
                data = json.loads(msg)
                if data.get("type") == kind:
                    return data
        raise TimeoutError(f"no {kind} message in {timeout} s")

    def close(self) -> None:
        self.ws.close()


class SteppingPlant(Protocol):
    """A thread that steps the console in its harness ``h`` until ``halt`` is set."""

    h: ModuleHarness
    halt: threading.Event

    def start(self) -> None: ...

    def join(self, timeout: float | None = None) -> None: ...


S = TypeVar("S", bound=SteppingPlant)


@contextmanager
def stepping(plant: S) -> Iterator[S]:
    """``plant``'s harness entered and ``plant`` running; halted and the harness closed after
    (unless the test did so first: :func:`stop_stepping`)."""
    plant.h.__enter__()
    plant.start()
    try:
        yield plant
    finally:
        stop_stepping(plant)


def stop_stepping(plant: SteppingPlant) -> None:
    """Halt ``plant`` and close its harness, once (the run's end, in the middle of a test)."""
    if plant.halt.is_set():
        return
    plant.halt.set()
    plant.join(5)
    plant.h.__exit__(None, None, None)
