"""Pure decisions on the operator's actions: is this click, box, resume or start acceptable now?

Each function returns the thing to send, or raises :class:`Refused` with the message for the
page and the log (what was expected, what was found). Times are seconds on the run's clock.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass

from umbra.connectors.commands import Seed
from umbra.connectors.messages import Contour
from umbra.connectors.tracking import TrackStatus

MIN_BOX_PX = 4.0


class Refused(ValueError):
    """An action the console does not pass on; ``str()`` says why."""


@dataclass(frozen=True)
class ShownFrame:
    """A frame the console sent to the pages: its ``seq``, ``stamp`` (the capture of its
    image, on the run's clock) [s] and size [px]."""

    seq: int
    stamp: float
    width: int
    height: int


class FrameHistory:
    """The last frames sent to the pages, so a click can be checked against the image it was
    made on (stale page, outside the image)."""

    def __init__(self, keep: int = 120) -> None:
        self._frames: collections.OrderedDict[int, ShownFrame] = collections.OrderedDict()
        self.keep = keep

    def add(self, frame: ShownFrame) -> None:
        self._frames[frame.seq] = frame
        while len(self._frames) > self.keep:
            self._frames.popitem(last=False)

    @property
    def latest(self) -> ShownFrame | None:
        """The newest frame shown (None before the first)."""
        return next(reversed(self._frames.values()), None)

    def frame_for(self, seq: int, now: float, max_age: float) -> ShownFrame:
        """The frame ``seq``, when it is younger than ``max_age`` at ``now``."""
        frame = self._frames.get(seq)
        if frame is None:
            raise Refused(
                f"stale page: the image you acted on (frame {seq}) is no longer live; "
                "expected a frame from the last "
                f"{max_age:.2f} s (reload the page if the video is frozen)"
            )
        age = now - frame.stamp
        if age > max_age:
            raise Refused(
                f"stale page: the image you acted on is {age:.3f} s old, expected at most "
                f"{max_age:.3f} s"
            )
        return frame


def _inside(frame: ShownFrame, u: float, v: float, what: str) -> None:
    if not (0.0 <= u < frame.width and 0.0 <= v < frame.height):
        raise Refused(
            f"{what} outside the image: expected 0 <= u < {frame.width} and 0 <= v < "
            f"{frame.height} px, found ({u:.1f}, {v:.1f})"
        )


def point_seed(frame: ShownFrame, u: float, v: float) -> Seed:
    """A point seed at ``(u, v)`` [px] for vsSnake."""
    _inside(frame, u, v, "click")
    return Seed.point(float(u), float(v))


def box_seed(frame: ShownFrame, u0: float, v0: float, u1: float, v1: float) -> Seed:
    """A box seed ``[u_min, v_min, u_max, v_max]`` [px] from a dragged box (any corner order)."""
    _inside(frame, u0, v0, "box corner")
    _inside(frame, u1, v1, "box corner")
    seed = Seed.box(float(u0), float(v0), float(u1), float(v1))
    width, height = seed.uv[2] - seed.uv[0], seed.uv[3] - seed.uv[1]
    if width < MIN_BOX_PX or height < MIN_BOX_PX:
        raise Refused(
            f"box too small: expected at least {MIN_BOX_PX:.0f} x {MIN_BOX_PX:.0f} px, found "
            f"{width:.1f} x {height:.1f}"
        )
    return seed


def check_snake_healthy(
    contour: Contour | None, contour_age: float, max_age: float, what: str
) -> None:
    """Resume and start need a healthy snake: tracking, with a fresh contour."""
    if contour is None or not math.isfinite(contour_age):
        raise Refused(f"{what} refused: expected a tracking snake, found no contour yet")
    if contour.status == TrackStatus.FAILED:
        raise Refused(
            f"{what} refused: the snake is not healthy "
            f"({contour.reason or 'sanity check failed'}); click the patch to re-seed it first"
        )
    if contour.status != TrackStatus.TRACKING:
        raise Refused(
            f"{what} refused: expected a tracking snake, found `{contour.status}` "
            f"({contour.reason or 'no seed'}); click the patch to seed it"
        )
    if contour_age > max_age:
        raise Refused(
            f"{what} refused: the snake's contour is {contour_age:.2f} s old, expected at most "
            f"{max_age:.2f} s"
        )
