"""The operator's commands as types: the grab's, the gripper's, the run's end, and seeds.

Each command names its action with an enum, so a word the receiver does not know cannot be sent
(it is refused when the sample is decoded) and ``umbra check`` refuses a gripper command wired to
a grab's input. The station's page speaks JSON; the console turns each action into one of these.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from umbra.connectors.messages import Message
from umbra.connectors.reasons import Code

_F8 = "float64"


class GrabAction(Code):
    """The operator's commands to a grab (vsServo): ``start`` is ``resume`` (a new grab from a
    stopped stage), ``pause`` holds the arm, ``abort`` stops and opens the gripper."""

    START = "start"
    PAUSE = "pause"
    RESUME = "resume"
    ABORT = "abort"


class GrabCommand(Message, frozen=True, kw_only=True):
    """One operator command to the grab."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "action": "GrabAction: " + ", ".join(f'"{m}"' for m in GrabAction),
    }

    action: GrabAction


class GripperAction(Code):
    """Open or close the gripper."""

    OPEN = "open"
    CLOSE = "close"


class GripperCommand(Message, frozen=True, kw_only=True):
    """One gripper command (a grab's, a path's), passed by the guard to the joint driver."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "action": "GripperAction: " + ", ".join(f'"{m}"' for m in GripperAction),
    }

    action: GripperAction


class StopRun(Message, frozen=True, kw_only=True):
    """The operator's *Stop*: the run's judge ends the run as a normal stop."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "by": "who asked: the name of the page holding control (empty: unknown)",
    }

    by: str = ""


class SeedShape(Code):
    """A seed is a point clicked on the target or a box dragged around it."""

    POINT = "point"
    BOX = "box"


class Seed(Message, frozen=True, kw_only=True):
    """Where a contour tracker should start, in image pixels (u right, v down): a ``point``
    ``uv = [u, v]`` on the target, or a ``box`` ``uv = [u_min, v_min, u_max, v_max]`` around it."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "shape": '"point" or "box"',
        "uv": f"{_F8} (2,) px [u, v] for a point, (4,) px [u_min, v_min, u_max, v_max] for a box",
    }

    shape: SeedShape
    uv: np.ndarray

    #: The number of pixel coordinates of each shape.
    SIZES: ClassVar[dict[str, int]] = {SeedShape.POINT: 2, SeedShape.BOX: 4}

    @classmethod
    def point(cls, u: float, v: float) -> Seed:
        """A point seed at ``(u, v)`` [px]."""
        return cls(shape=SeedShape.POINT, uv=np.array([u, v], dtype=float))

    @classmethod
    def box(cls, u0: float, v0: float, u1: float, v1: float) -> Seed:
        """A box seed from two corners [px], in any order."""
        corners = [min(u0, u1), min(v0, v1), max(u0, u1), max(v0, v1)]
        return cls(shape=SeedShape.BOX, uv=np.array(corners, dtype=float))

    def problem(self) -> str:
        """What is wrong with this seed ("" when it is sound): the shape's number of finite
        coordinates, and a box with room inside."""
        uv = np.asarray(self.uv, dtype=float).ravel()
        want = self.SIZES.get(self.shape)
        if want is None or uv.size != want or not np.all(np.isfinite(uv)):
            return (
                f"expected a {self.shape} seed of {want} finite pixel coordinates, "
                f"found {uv.tolist()}"
            )
        if self.shape == SeedShape.BOX and (uv[2] <= uv[0] or uv[3] <= uv[1]):
            return (
                "expected a box seed [u_min, v_min, u_max, v_max], found an empty one "
                f"{uv.tolist()}"
            )
        return ""
