"""What a camera ``source`` names, as OpenCV would open it, and why it cannot be opened.

A source is one of (:meth:`CaptureSource.parse`):

* a device index, written as a number (``source: 0`` or ``"0"``), or a device path
  (``/dev/video0``, ``/dev/v4l/by-id/...``);
* a stream URL (``rtsp://``, ``http://``, ``https://``, ``tcp://``, ``udp://``...);
* an image sequence, a printf pattern (``imgs/img_%04d.png``): OpenCV starts at the first index
  0..4 that exists and plays the files in order;
* a single still image (``.png``, ``.jpg``, ...): sent again at every step;
* otherwise a video file.

:func:`source_problem` checks what can be checked before anything starts (files that are not
there, a pattern whose first image is missing, a device path that does not exist);
:func:`probe_stream` tells a refused, timed-out or unknown host from a stream OpenCV cannot
decode. Every message names the cause: not found, refused, timed out, cannot decode.
"""

from __future__ import annotations

import contextlib
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal
from urllib.parse import urlsplit

from pydantic import AfterValidator, BeforeValidator

from umbra.connectors.safe_yaml import boolean_hint

SourceKind = Literal["device", "file", "sequence", "image", "url"]

IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".jpe", ".bmp", ".dib", ".tif", ".tiff", ".webp", ".pbm", ".pgm"}
    | {".ppm", ".pnm", ".pxm", ".jp2", ".exr", ".hdr", ".sr", ".ras"}
)
"""Still-image formats OpenCV's imread reads."""
SEQUENCE_FIRST_INDICES = range(5)
"""OpenCV's image-sequence reader starts at the first of these indices that exists."""
DEFAULT_PORTS = {"http": 80, "https": 443, "rtsp": 554, "rtsps": 322, "rtmp": 1935}


class CaptureError(ValueError):
    """A capture source could not be opened or read; the message names the cause."""


@dataclass(frozen=True)
class CaptureSource:
    """Where frames come from: ``kind`` and ``target`` (device index or path, file path, pattern
    or URL)."""

    kind: SourceKind
    target: int | str

    @classmethod
    def parse(cls, value: str | int) -> CaptureSource:
        """The source a parameter value names (see the module docstring)."""
        if isinstance(value, bool):
            raise CaptureError(f"expected a camera source, found the boolean {value}")
        if isinstance(value, int):
            return cls("device", value)
        text = value.strip()
        if text.isdigit():
            return cls("device", int(text))
        if "://" in text:
            return cls("url", text)
        if text.startswith("/dev/"):
            return cls("device", text)
        if "%" in Path(text).name:
            return cls("sequence", text)
        if Path(text).suffix.lower() in IMAGE_SUFFIXES:
            return cls("image", text)
        return cls("file", text)

    def describe(self) -> str:
        names = {
            "device": "camera device",
            "file": "video file",
            "sequence": "image sequence",
            "image": "image",
            "url": "stream",
        }
        return f"{names[self.kind]} {self.target}"

    @property
    def plays_in_order(self) -> bool:
        """Files and sequences: every frame once, in order (devices and streams: the newest)."""
        return self.kind in ("file", "sequence")


def sequence_first_files(pattern: str) -> list[Path]:
    """The files an image-sequence ``pattern`` may start with (indices 0..4)."""
    try:
        return [Path(pattern % index) for index in SEQUENCE_FIRST_INDICES]
    except (TypeError, ValueError) as exc:
        raise CaptureError(
            f"image sequence {pattern}: not a printf pattern with one integer field such as "
            f"img_%04d.png ({exc})"
        ) from None


def source_problem(source: CaptureSource, cwd: Path | None = None) -> str:
    """Why ``source`` cannot be opened, as far as the file system tells (empty: no problem
    seen); relative paths are taken from ``cwd`` (default: the working folder), as OpenCV does."""
    where = f", from {cwd or Path.cwd()}"
    target = str(source.target)
    if source.kind in ("file", "image"):
        path = Path(target)
        if not path.is_file():
            found = "a folder" if path.is_dir() else "no such file"
            return f"{source.describe()} not found ({found}{where})"
    elif source.kind == "sequence":
        try:
            first = sequence_first_files(target)
        except CaptureError as exc:
            return str(exc)
        if not any(p.is_file() for p in first):
            return (
                f"{source.describe()} not found (no {first[0]} .. {first[-1].name}: the first "
                f"image must have index 0 to {SEQUENCE_FIRST_INDICES[-1]}{where})"
            )
    elif source.kind == "device" and isinstance(source.target, str) and not Path(target).exists():
        return f"{source.describe()} not found (no such device)"
    return ""


def probe_stream(url: str, timeout_s: float) -> str:
    """Whether the host of a network stream accepts a TCP connection within ``timeout_s``:
    empty when it does (or the scheme is not TCP-based), else the cause: host not found,
    refused, timed out."""
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme == "udp" or not parts.hostname:
        return ""
    try:
        port = parts.port or DEFAULT_PORTS.get(scheme)
    except ValueError:
        return f"stream {url}: bad port in the URL"
    if port is None:
        return ""
    try:
        addresses = socket.getaddrinfo(parts.hostname, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        return f"stream {url}: host {parts.hostname} not found ({exc.strerror})"
    family, kind, proto, _, address = addresses[0]
    with contextlib.closing(socket.socket(family, kind, proto)) as probe:
        probe.settimeout(timeout_s)
        try:
            probe.connect(address)
        except ConnectionRefusedError:
            return f"stream {url}: connection refused by {parts.hostname}:{port}"
        except TimeoutError:
            where = f"{parts.hostname}:{port}"
            return f"stream {url}: connection to {where} timed out after {timeout_s:g} s"
        except OSError as exc:
            return (
                f"stream {url}: cannot connect to {parts.hostname}:{port} ({exc.strerror or exc})"
            )
    return ""


def _source_text(value: Any) -> Any:
    """A device index written as a number in YAML (``source: 0``) is the text ``"0"``."""
    if isinstance(value, bool):
        raise ValueError(
            f"expected `sim`, a device index, a device path, a file, an image sequence or a "
            f"stream URL, found the boolean {value}{boolean_hint(value)}"
        )
    return str(value) if isinstance(value, int) else value


def _source_exists(text: str) -> str:
    """Files, images and the first image of a sequence must exist (relative to the working
    folder, as OpenCV opens them); devices and URLs are checked where the module starts."""
    if text.strip() == "sim":
        return text
    source = CaptureSource.parse(text)
    if source.kind in ("file", "image", "sequence"):
        problem = source_problem(source)
        if problem:
            raise ValueError(f"expected `sim`, a device, a file or a stream URL: {problem}")
    return text


#: A DigiCam ``source`` parameter, checked before anything starts.
CameraSource = Annotated[str, BeforeValidator(_source_text), AfterValidator(_source_exists)]
