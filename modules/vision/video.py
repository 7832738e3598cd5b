"""Writing overlay frames to a video file with OpenCV (works with opencv-python-headless).

The codec follows the file name: ``.avi`` uses Motion-JPEG (``MJPG``), ``.mp4`` uses MPEG-4
part 2 (``mp4v``); both are built into OpenCV's FFmpeg backend and read back by
``cv2.VideoCapture``. H.264 (``avc1``) is not offered: the wheel's FFmpeg has no software
H.264 encoder.
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType

import numpy as np
from numpy.typing import NDArray

CODECS = {".avi": "MJPG", ".mp4": "mp4v"}


class VideoFileError(ValueError):
    """A video file could not be opened for writing, or a frame did not fit it."""


class VideoWriter:
    """Writes H x W x 3 uint8 BGR frames of one size to ``path`` at ``fps`` frames per second."""

    def __init__(self, path: str | Path, fps: float, size_wh: tuple[int, int]) -> None:
        import cv2

        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in CODECS:
            raise VideoFileError(
                f"{self.path}: video file must end in {' or '.join(CODECS)}, got '{suffix}'"
            )
        if fps <= 0:
            raise VideoFileError(f"{self.path}: frame rate must be > 0, got {fps}")
        self.size_wh = (int(size_wh[0]), int(size_wh[1]))
        self.frames = 0
        # cv2's stubs lack VideoWriter_fourcc, which the module has.
        fourcc = cv2.VideoWriter_fourcc(*CODECS[suffix])  # type: ignore[attr-defined]
        self._writer = cv2.VideoWriter(str(self.path), fourcc, float(fps), self.size_wh)
        if not self._writer.isOpened():
            raise VideoFileError(f"{self.path}: cannot open for writing ({CODECS[suffix]} codec)")

    def check_frame(self, frame: NDArray[np.uint8]) -> None:
        """VideoFileError unless ``frame`` is H x W x 3 of the size given at opening."""
        height, width = frame.shape[:2]
        if (width, height) != self.size_wh or frame.ndim != 3 or frame.shape[2] != 3:
            raise VideoFileError(
                f"{self.path}: frames must be {self.size_wh[0]}x{self.size_wh[1]}x3, "
                f"got shape {frame.shape}"
            )

    def write(self, frame: NDArray[np.uint8]) -> None:
        """Append one frame; it must have the size given at opening."""
        self.check_frame(frame)
        self._writer.write(np.ascontiguousarray(frame, dtype=np.uint8))
        self.frames += 1

    def close(self) -> None:
        """Finish the file (idempotent)."""
        self._writer.release()

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
