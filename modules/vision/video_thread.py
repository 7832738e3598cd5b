"""A video file written from a thread of its own, so encoding never holds a tick back.

Encoding a 720p frame as Motion-JPEG costs about 4 ms, all of it inside OpenCV, which releases
the GIL: on its own thread it overlaps the vision loop instead of adding to its frame time. Frames
wait in a bounded queue (``depth``). When the queue is full, ``wait=True`` (the sim clock, where
nothing is real time) waits for room, so the file holds every frame; ``wait=False`` (the real
clock) drops the frame and counts it in ``dropped``. A frame of another size than the first is
refused where it is offered (``VideoFileError``), as :class:`VideoWriter` refuses it. The thread
runs in the background (``SCHED_BATCH``): under CPU starvation the file loses frames (counted),
the vision loop none of its time.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.threads import background
from umbra.modules.vision.video import VideoWriter

_CLOSE = None


class ThreadedVideoWriter:
    """Writes H x W x 3 uint8 BGR frames of one size to ``path`` at ``fps`` frames per second,
    on a thread of its own (see the module docstring)."""

    def __init__(
        self,
        path: str | Path,
        fps: float,
        size_wh: tuple[int, int],
        *,
        wait: bool,
        depth: int = 8,
    ) -> None:
        self._writer = VideoWriter(path, fps, size_wh)  # errors of the file: here, at once
        self.path = self._writer.path
        self.size_wh = self._writer.size_wh
        self.error = ""
        self._refused = 0  # frames the caller offered that found no room (or no encoder)
        self._lost = 0  # frames queued that the encoder could not write (after an error)
        self._wait = wait
        self._queue: queue.Queue[NDArray[np.uint8] | None] = queue.Queue(maxsize=max(1, depth))
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="umbra-video", daemon=True)
        self._thread.start()

    @property
    def frames(self) -> int:
        """Frames written to the file so far."""
        return self._writer.frames

    @property
    def dropped(self) -> int:
        """Frames offered that are not in the file: no room, or the encoder failed."""
        return self._refused + self._lost

    def write(self, frame: NDArray[np.uint8]) -> bool:
        """Queue one frame (the caller must not change it afterwards); False when dropped."""
        self._writer.check_frame(frame)
        if not self._put(frame, self._wait):
            self._refused += 1
            return False
        return True

    def close(self) -> None:
        """Write the queued frames and finish the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._put(_CLOSE, wait=True, closing=True)
        self._thread.join()
        self._writer.close()

    def _put(self, item: NDArray[np.uint8] | None, wait: bool, closing: bool = False) -> bool:
        """Queue ``item``; never waits on an encoder that has stopped."""
        while self._thread.is_alive():
            if not closing and (self._closed or self.error):
                return False
            try:
                self._queue.put(item, timeout=0.2 if wait else None, block=wait)
                return True
            except queue.Full:
                if not wait:
                    return False
        return False

    def _run(self) -> None:
        background()  # under starvation the operator's video gives way, never the vision loop
        try:
            while (frame := self._queue.get()) is not _CLOSE:
                if self.error:
                    self._lost += 1
                    continue
                try:
                    self._writer.write(frame)
                except Exception as exc:  # a full disk must not end the run, nor stop the queue
                    self.error = f"{self.path}: {exc}"
                    self._lost += 1
        except BaseException as exc:  # the thread ends: say so, so nobody waits on it
            self.error = self.error or f"{self.path}: video encoder stopped: {exc!r}"
            raise
