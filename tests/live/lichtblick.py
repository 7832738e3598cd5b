"""The prebuilt Lichtblick web app (``../shared/viewers/``) served on loopback for browser tests:
a page with a layout of our own, opened in Debian's Chromium with software WebGL."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tarfile
import urllib.request
from pathlib import Path

import pytest

from tests.browser import CHROMIUM_ARGS
from tests.poll import wait_for

VIEWERS = Path(__file__).resolve().parents[3] / "shared" / "viewers"
TARBALL = VIEWERS / "lichtblick-1.10.8-web.tar.xz"
#: WebGL in software, for the 3-D panel (the viewers' README)
WEBGL_ARGS = [*CHROMIUM_ARGS, "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]

needs_lichtblick = pytest.mark.skipif(
    not TARBALL.exists(), reason=f"needs the prebuilt Lichtblick web app at {TARBALL}"
)
_LAYOUT = re.compile(r"LICHTBLICK_SUITE_DEFAULT_LAYOUT = \{.*?\};\n", re.S)


def unpack(folder: Path) -> Path:
    """The web app unpacked into ``folder``; its root."""
    with tarfile.open(TARBALL) as tar:
        tar.extractall(folder, filter="data")
    return folder / ".webpack"


def with_layout(root: Path, name: str, layout: dict) -> str:
    """A copy of ``probe.html`` named ``name`` whose default layout is ``layout``."""
    page = (root / "probe.html").read_text()
    text = f"LICHTBLICK_SUITE_DEFAULT_LAYOUT = {json.dumps(layout)};\n"
    page, count = _LAYOUT.subn(lambda _m: text, page)
    assert count == 1, "probe.html no longer sets a default layout"
    (root / name).write_text(page)
    return name


class Served:
    """``serve.py ROOT PORT NAME=FILE...`` (HTTP Range for the remote-file source)."""

    def __init__(self, root: Path, port: int, files: dict[str, Path] | None = None) -> None:
        extra = [f"{k}={v}" for k, v in (files or {}).items()]
        self.proc = subprocess.Popen(
            [sys.executable, str(VIEWERS / "serve.py"), str(root), str(port), *extra]
        )
        self.base = f"http://127.0.0.1:{port}"

        def up() -> bool:
            try:
                urllib.request.urlopen(f"{self.base}/probe.html", timeout=1).close()
            except OSError:
                return False
            return True

        try:
            wait_for(up, 20, "the viewer's server to start", 0.2)
        except AssertionError:
            self.close()
            raise

    def close(self) -> None:
        self.proc.terminate()
        self.proc.wait(10)


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def colours(png: bytes, box: tuple[int, int, int, int]) -> int:
    """Distinct colours (coarsely quantized) in ``box`` (x0, y0, x1, y1) of a screenshot: a
    video frame or a textured image has hundreds, a grid on a plain background a handful."""
    import cv2
    import numpy as np

    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    x0, y0, x1, y1 = box
    part = img[y0:y1, x0:x1] // 16
    keys = part[..., 0].astype(int) * 256 + part[..., 1].astype(int) * 16 + part[..., 2]
    return int(np.unique(keys).size)
