"""A video file written from a thread of its own, so encoding never holds a tick back.

Encoding a 720p frame as Motion-JPEG costs about 4 ms, all of it inside OpenCV, which releases
the GIL: on its own thread it overlaps the vision loop instead of adding to its frame time. Frames
wait in a bounded queue (``depth``). When the queue is full, ``wait=True`` (the sim clock, where
nothing is real time) waits for room, so the file holds every frame; ``wait=False`` (the real
clock) drops the frame and counts it in ``dropped``. A frame of another size than the first is
refused where it is offered (``VideoFileError``), as :class:`VideoWriter` refuses it.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from modules.vision.video import VideoWriter

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
        self.dropped = 0
        self.error = ""
        self._wait = wait
        self._queue: queue.Queue[NDArray[np.uint8] | None] = queue.Queue(maxsize=max(1, depth))
        self._thread = threading.Thread(target=self._run, name="umbra-video", daemon=True)
        self._thread.start()
        self._closed = False

    @property
    def frames(self) -> int:
        """Frames written to the file so far."""
        return self._writer.frames

    def write(self, frame: NDArray[np.uint8]) -> bool:
        """Queue one frame (the caller must not change it afterwards); False when dropped."""
        self._writer.check_frame(frame)
        if self._closed or self.error:
            self.dropped += 1
            return False
        try:
            self._queue.put(frame, block=self._wait)
        except queue.Full:
            self.dropped += 1
            return False
        return True

    def close(self) -> None:
        """Write the queued frames and finish the file (idempotent)."""
        if self._closed:
            return
        self._closed = True
        self._queue.put(_CLOSE)
        self._thread.join()
        self._writer.close()

    def _run(self) -> None:
        while (frame := self._queue.get()) is not _CLOSE:
            if self.error:
                continue
            try:
                self._writer.write(frame)
            except Exception as exc:  # a full disk must not end the run, nor stop the queue
                self.error = f"{self.path}: {exc}"
