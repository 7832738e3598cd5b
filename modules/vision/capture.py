"""Frames from OpenCV capture (device, video file, image sequence, still image, stream URL),
read in a thread.

The reader thread is the only place that blocks on the device; the owner takes frames without
waiting. A device or a stream keeps only its latest frame (old frames are dropped, as a frame
grabber does); a video file or an image sequence keeps every frame, in order, in a short queue,
so that playback delivers each frame once. At the end of a file the reader loops, or stops and
says so; a file that cannot be read again from its start ends there. A still image is decoded
once and needs no thread (:attr:`CaptureReader.still`). What a source names and why it cannot
be opened is :mod:`umbra.modules.vision.capture_source`.

A device's or stream's frame carries its capture time [s, ``time.monotonic()``]: the driver's
buffer stamp where the backend gives one on that clock, else the moment ``grab()`` dequeued it,
before decoding (:mod:`umbra.modules.vision.capture_time`).
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from typing import TYPE_CHECKING, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from umbra.modules.vision.capture_source import (
    CaptureError,
    CaptureSource,
    probe_stream,
    source_problem,
)
from umbra.modules.vision.capture_time import capture_time

if TYPE_CHECKING:
    from cv2.typing import MatLike

__all__ = ["CaptureError", "CaptureReader", "CaptureSource", "LiveFrame"]


class LiveFrame(NamedTuple):
    """The newest frame of a device or stream: its number (1, 2, ...), its pixels, its capture
    time [s, ``time.monotonic()``] and where that time comes from (``"driver"`` or ``"grab"``)."""

    number: int
    pixels: NDArray[np.uint8]
    captured_at: float
    stamped_by: str


def _as_bgr(frame: MatLike, size_wh: tuple[int, int] | None) -> NDArray[np.uint8]:
    """A decoded frame as contiguous 8-bit BGR, resized to ``size_wh`` (width, height) [px]."""
    if frame.ndim == 2:
        frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
    elif frame.shape[2] == 4:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    if size_wh is not None and (frame.shape[1], frame.shape[0]) != size_wh:
        frame = cv2.resize(frame, size_wh, interpolation=cv2.INTER_AREA)
    # imread(IMREAD_COLOR) and VideoCapture deliver 8-bit frames: the dtype converts nothing,
    # it states what the array holds.
    return np.ascontiguousarray(frame, dtype=np.uint8)


class CaptureReader:
    """Opens ``source`` at once (raising :class:`CaptureError` if it cannot deliver a frame) and
    reads it in a daemon thread after :meth:`start`.

    ``size_wh``: frames are resized to this (width, height) when given (and a device is asked
    for it); ``fps``: frame rate asked of a device (0: its own); ``loop``: a file starts over at
    its end instead of ending; ``open_timeout_s``: how long a stream may take to open.
    """

    def __init__(
        self,
        source: CaptureSource,
        size_wh: tuple[int, int] | None = None,
        fps: float = 0.0,
        loop: bool = True,
        open_timeout_s: float = 5.0,
        file_queue: int = 4,
    ) -> None:
        self.source = source
        self.size_wh = size_wh
        self.loop = loop
        self.frames_read = 0
        self.ended = threading.Event()
        self.failed_reads = 0
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._latest: LiveFrame | None = None
        self._first_at = (0.0, "grab")  # capture time of the frame read while opening
        self._queue: queue.Queue[NDArray[np.uint8]] = queue.Queue(maxsize=max(file_queue, 1))
        self._thread: threading.Thread | None = None
        self.loop_failed = False
        self.still: NDArray[np.uint8] | None = None
        """The frame of a still image (sent again at every step); None for other sources."""
        problem = source_problem(source)
        if problem:
            raise CaptureError(problem)
        if source.kind == "image":
            image = cv2.imread(str(source.target), cv2.IMREAD_COLOR)
            if image is None:
                raise CaptureError(
                    f"{source.describe()}: cannot decode (not an image OpenCV reads)"
                )
            self.still = _as_bgr(image, size_wh)
            self._first: NDArray[np.uint8] | None = None
            self.ended.set()
            return
        if source.kind == "url":
            unreachable = probe_stream(str(source.target), open_timeout_s)
            if unreachable:
                raise CaptureError(unreachable)
        self._open_timeout_s = open_timeout_s
        self._capture = self._open(fps)
        first, self._first_at = self._read()
        if first is None:
            self._capture.release()
            raise CaptureError(f"{source.describe()} opened but delivered no frame (cannot decode)")
        self._first = _as_bgr(first, size_wh)

    def _read(self) -> tuple[MatLike | None, tuple[float, str]]:
        """One frame (None: none) and, for a live one, its capture time [s] and its source."""
        if self.is_file:
            ok, frame = self._capture.read()
            return (frame if ok else None), (0.0, "grab")
        if not self._capture.grab():
            return None, (0.0, "grab")
        grabbed = time.monotonic()
        driver_ms = (
            self._capture.get(cv2.CAP_PROP_POS_MSEC) if self.source.kind == "device" else None
        )
        captured = capture_time(driver_ms, grabbed)
        ok, frame = self._capture.retrieve()
        return (frame if ok else None), captured

    def _video_capture(self) -> cv2.VideoCapture:
        source = self.source
        if source.kind == "url":
            timeout = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, int(1000 * self._open_timeout_s)]
            return cv2.VideoCapture(str(source.target), cv2.CAP_ANY, timeout)
        return cv2.VideoCapture(source.target)  # a `%` pattern: OpenCV's image-sequence reader

    def _open(self, fps: float) -> cv2.VideoCapture:
        source = self.source
        capture = self._video_capture()
        if not capture.isOpened():
            capture.release()
            if source.kind == "device":
                reason = "no such camera, or it is busy or not readable (permissions)"
            else:
                reason = "cannot decode: OpenCV has no reader for it"
            raise CaptureError(f"cannot open {source.describe()} ({reason})")
        if source.kind == "device":
            if self.size_wh is not None:
                capture.set(cv2.CAP_PROP_FRAME_WIDTH, self.size_wh[0])
                capture.set(cv2.CAP_PROP_FRAME_HEIGHT, self.size_wh[1])
            if fps > 0:
                capture.set(cv2.CAP_PROP_FPS, fps)
        return capture

    @property
    def is_file(self) -> bool:
        """Frames play once each, in order (a video file or an image sequence)."""
        return self.source.plays_in_order

    @property
    def is_still(self) -> bool:
        return self.still is not None

    def start(self) -> None:
        """Start the reader thread (a still image needs none)."""
        if self.is_still:
            return
        self._thread = threading.Thread(
            target=self._run, name=f"capture-{self.source.target}", daemon=True
        )
        self._thread.start()

    def _publish(
        self, frame: NDArray[np.uint8], captured: tuple[float, str] = (0.0, "grab")
    ) -> bool:
        """Hand a frame over (a live one captured at ``captured``: time [s], its source);
        False when asked to stop while waiting for queue space."""
        self.frames_read += 1
        if not self.is_file:
            with self._lock:
                self._latest = LiveFrame(self.frames_read, frame, *captured)
            return True
        while not self._stop.is_set():
            try:
                self._queue.put(frame, timeout=0.05)
                return True
            except queue.Full:
                continue
        return False

    def _run(self) -> None:
        first, self._first = self._first, None
        if first is not None and not self._publish(first, self._first_at):
            return
        while not self._stop.is_set():
            frame, captured = self._read()
            if frame is not None:
                self.failed_reads = 0
                if not self._publish(_as_bgr(frame, self.size_wh), captured):
                    return
                continue
            if self.is_file:
                if self.loop and self.frames_read > 0 and self._rewind():
                    continue
                self.ended.set()
                return
            # A device or stream that fails to deliver: keep trying, gently.
            self.failed_reads += 1
            self._stop.wait(0.01)

    def _rewind(self) -> bool:
        """Back to the first frame, which is read and handed over here: a file that cannot be
        read again from its start (False) ends instead of spinning."""
        if not self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0):
            self._capture.release()
            self._capture = self._video_capture()
        ok, frame = self._capture.read() if self._capture.isOpened() else (False, None)
        if not ok or frame is None:
            self.loop_failed = True
            return False
        return self._publish(_as_bgr(frame, self.size_wh))

    def latest(self) -> LiveFrame | None:
        """The newest frame of a device or stream; None before one."""
        with self._lock:
            return self._latest

    def next_frame(self, timeout_s: float = 0.0) -> NDArray[np.uint8] | None:
        """The next frame of a file in order; None when none is ready within ``timeout_s``."""
        try:
            if timeout_s > 0:
                return self._queue.get(timeout=timeout_s)
            return self._queue.get_nowait()
        except queue.Empty:
            return None

    def drained(self) -> bool:
        """A file that has ended and whose frames have all been taken."""
        return self.ended.is_set() and self._queue.empty()

    def close(self) -> None:
        """Stop the thread and release the device (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            if self._thread.is_alive():
                return  # stuck in a driver call: releasing under it could crash; it is a daemon
            self._thread = None
        capture = getattr(self, "_capture", None)
        if capture is not None:
            with contextlib.suppress(cv2.error):
                capture.release()
