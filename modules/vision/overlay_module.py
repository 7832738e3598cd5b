"""Overlay: draws the snake, its sanity shapes and the servo stage on the camera image."""

from __future__ import annotations

from pathlib import Path, PurePath
from typing import Annotated

import numpy as np
from pydantic import AfterValidator

from umbra.connectors import Input, Module, Output, Parameters, UserError, param
from umbra.connectors.messages import Contour, Image, Status
from umbra.connectors.params import RunFile
from umbra.connectors.status_figures import error_figure
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.overlay import draw_overlay
from umbra.modules.vision.sanity import SanityLimits, bounding_shapes
from umbra.modules.vision.video import VideoFileError
from umbra.modules.vision.video_thread import ThreadedVideoWriter

#: Containers the operator's video can be written in.
VIDEO_SUFFIXES = (".avi", ".mp4")


def _video_container(path: str) -> str:
    if path and PurePath(path).suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"expected a file ending in .avi or .mp4, found {path!r}")
    return path


#: The operator's video: inside the run folder, in a container OpenCV writes.
VideoFile = Annotated[RunFile, AfterValidator(_video_container)]


class Overlay(Module["Overlay.Params"]):
    """The operator's view: each image with the snake drawn on it, and optionally a video file.

    Draws the contour (offending vertices in red), the outer rectangle and inner ellipse of the
    sanity check (rebuilt from the contour with ``rectangle_margin`` and ``ellipse_scale``; keep
    them equal to the snake's), the centroid and principal axes, and text lines: the contour's
    status and reason, and the servo's stage and message when ``status`` is connected. With
    ``video`` set, every drawn image is also written to that file in the run's output folder
    (``.avi``: Motion-JPEG, ``.mp4``: MPEG-4), at ``video_fps``, encoded on a thread of its own
    (on the real clock a frame the encoder cannot take is dropped and counted in the summary's
    ``video_dropped``; on the sim clock the file holds every frame).
    """

    TYPE = "Overlay"

    class Params(Parameters):
        video: VideoFile = param(
            "", "video file to write in the run folder (.avi or .mp4); empty: none"
        )
        video_fps: float = param(30.0, "frame rate written in the video file", unit="Hz", gt=0)
        rectangle_margin: float = param(0.12, "outer rectangle growth, as the snake's", ge=0)
        ellipse_scale: float = param(0.85, "inner ellipse scale, as the snake's", gt=0, le=1)
        max_contour_age: float = param(0.5, "older contours are not drawn", unit="s", gt=0)

    image = Input(Image, trigger=True, doc="camera frames (BGR)")
    contour = Input(Contour, required=False, doc="tracked contour from vsSnake")
    status = Input(Status, required=False, doc="stage and messages from vsServo")
    overlay = Output(Image, doc="the image with the drawing")

    def start(self) -> None:
        self._limits = SanityLimits(
            rectangle_margin=self.params.rectangle_margin, ellipse_scale=self.params.ellipse_scale
        )
        self._writer: ThreadedVideoWriter | None = None
        self._path: Path | None = None  # the video file; None: no video
        if self.params.video:
            self._path = self.context.output_dir / self.params.video
            self._path.parent.mkdir(parents=True, exist_ok=True)
        self._drawn = 0

    def stop(self) -> None:
        if self._writer is not None:
            self._writer.close()
            if self._writer.error:
                self.log.error("%s: video not finished: %s", self.name, self._writer.error)

    def summary(self) -> dict[str, object]:
        out: dict[str, object] = {"frames": self._drawn}
        if self._writer is not None:
            out["video"] = str(self._path)
            out["video_frames"] = self._writer.frames
            out["video_dropped"] = self._writer.dropped
            if self._writer.error:
                out["video_error"] = self._writer.error
        return out

    def step(self, now: float) -> None:
        if not self.image.fresh:
            return
        sample = self.image.get(now)
        if sample is None:
            return
        contour = self.contour.get(now)
        if contour is not None and self.contour.age(now) > self.params.max_contour_age:
            contour = None
        lines = self._lines(sample, contour, self.status.get(now))
        drawn = self._draw(np.asarray(sample.pixels), contour, lines)
        self.overlay.send(Image(pixels=drawn, frame=sample.frame, stamp=sample.stamp))
        self._drawn += 1
        if self._path is not None:
            self._write(self._path, drawn)

    @staticmethod
    def _lines(sample: Image, contour: Contour | None, status: Status | None) -> list[str]:
        lines = []
        if status is not None:
            text = f"stage: {status.stage}"
            if status.message:
                text += f" - {status.message}"
            lines.append(text)
            if status.assist:
                lines.append(f"operator: {status.reason or 'assistance requested'}")
            if status.values:
                lines.append("  ".join(error_figure(k, v) for k, v in status.values.items()))
        if contour is None:
            lines.append("snake: no contour")
        else:
            text = f"snake: {contour.status}"
            if contour.reason:
                text += f" - {contour.reason}"
            lines.append(text)
        if sample.stale:
            lines.append("camera: STALE (no new frames)")
        return lines

    def _draw(self, pixels: np.ndarray, contour: Contour | None, lines: list[str]) -> np.ndarray:
        if contour is None or len(contour.vertices) < 3:
            return draw_overlay(pixels, lines=lines)
        vertices = np.asarray(contour.vertices, dtype=float)
        try:
            features = polygon_features(vertices)
        except ValueError:
            return draw_overlay(pixels, vertices, lines=lines, offending=contour.offending)
        rectangle, ellipse = bounding_shapes(features, self._limits)
        return draw_overlay(
            pixels,
            vertices,
            lines=lines,
            features=features,
            offending=contour.offending,
            outer_rectangle=rectangle,
            inner_ellipse=ellipse,
        )

    def _write(self, path: Path, drawn: np.ndarray) -> None:
        """Append ``drawn`` to the video at ``path``, opened at the first frame."""
        if self._writer is None:
            try:
                self._writer = ThreadedVideoWriter(
                    path,
                    self.params.video_fps,
                    (drawn.shape[1], drawn.shape[0]),
                    wait=self.context.clock == "sim",  # the sim clock's file holds every frame
                )
            except VideoFileError as exc:
                raise UserError(f"{self.name}: {exc}") from None
        if (drawn.shape[1], drawn.shape[0]) != self._writer.size_wh:
            self.log.warning("%s: image size changed; frame not written to the video", self.name)
            return
        self._writer.write(drawn)
