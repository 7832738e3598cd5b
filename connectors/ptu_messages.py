"""Message types of a pan/tilt unit: its command and its state.

Spoken by the PTU module and by who aims it (Active Sketch). Angles in radians, rates in
radians per second, points in metres in ``frame``.

Flow::

    sketch --PtuCommand--> PTU --PtuState--> cameras, sketch
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from umbra.connectors.messages import DEVICE_OK, Message
from umbra.connectors.reasons import Code

_F8 = "float64"


class PtuMode(Code):
    """How a PTU command aims: at angles, or at a point."""

    ANGLES = "angles"  #: go to ``pan``, ``tilt``
    POINT = "point"  #: aim the camera's optical axis at ``point``


class PtuCommand(Message, frozen=True, kw_only=True):
    """A pan/tilt unit command: ``mode`` "angles" (go to ``pan``, ``tilt`` [rad]) or "point"
    (aim the camera's optical axis at ``point`` (3,, m) in ``frame``)."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "mode": "PtuMode: " + ", ".join(f'"{m}"' for m in PtuMode),
        "pan": "rad",
        "tilt": "rad",
        "point": f"{_F8} (3,), m in `frame`",
        "frame": "frame of `point`",
    }

    mode: PtuMode
    pan: float = 0.0
    tilt: float = 0.0
    point: np.ndarray = np.zeros(3)
    frame: str = "base"


class PtuState(Message, frozen=True, kw_only=True):
    """A pan/tilt unit's angles [rad] and rates [rad/s]; ``moving`` while slewing; ``status``."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "pan": "rad",
        "tilt": "rad",
        "pan_rate": "rad/s",
        "tilt_rate": "rad/s",
        "moving": "true while slewing",
        "status": f'"{DEVICE_OK}" or what is wrong',
    }

    pan: float
    tilt: float
    pan_rate: float = 0.0
    tilt_rate: float = 0.0
    moving: bool = False
    status: str = DEVICE_OK

    @property
    def ok(self) -> bool:
        """Nothing is wrong with the pan/tilt unit (its ``status`` is ``DEVICE_OK``)."""
        return self.status == DEVICE_OK
