"""The true objects of a simulated world, for the renderers and the 3-D view.

Sent by the simulated world (SketchWorld), drawn by the simulated cameras and the 3-D view.
Poses are 4 x 4 homogeneous transforms (metres) in ``frame``.
"""

from __future__ import annotations

from typing import ClassVar

import msgspec
import numpy as np

from umbra.connectors.messages import Message
from umbra.connectors.reasons import Code

_F8 = "float64"


class SolidKind(Code):
    """The shape of a scene object."""

    BOX = "box"  #: sizes: edge lengths x, y, z, centred on the pose
    CYLINDER = "cylinder"  #: sizes: radius, radius, length along the pose's z, centred


class SceneObjects(Message, frozen=True, kw_only=True):
    """The true objects of the simulated world (for rendering and the 3-D view), in ``frame``.

    One row per solid: ``names``; ``kinds`` "box" (``sizes`` = edge lengths x, y, z, centred on
    the pose) or "cylinder" (``sizes`` = radius, radius, length along the pose's z, centred);
    ``poses`` (N x 4 x 4, m): T_base_object; ``colors`` (N x 3, uint8 RGB).
    ``values``: named state figures (e.g. ``door_angle`` [rad], ``gripper`` 0 .. 1).
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "names": "N object names",
        "kinds": "N kinds, SolidKind: " + ", ".join(f'"{k}"' for k in SolidKind),
        "poses": f"{_F8} (N, 4, 4), m: T_frame_object",
        "sizes": f"{_F8} (N, 3), m: box edges, or radius, radius, length",
        "colors": "uint8 (N, 3), RGB",
        "values": "map str -> float: named state figures",
        "frame": "frame of the poses",
    }

    names: tuple[str, ...]
    kinds: tuple[SolidKind, ...]
    poses: np.ndarray
    sizes: np.ndarray
    colors: np.ndarray
    values: dict[str, float] = msgspec.field(default_factory=dict)
    frame: str = "base"

    FRAME_KIND: ClassVar[str] = "frame"

    def __post_init__(self) -> None:
        """Kinds made in this process as plain words become their :class:`SolidKind` (an
        unknown word raises ``ValueError``, as decoding refuses it): every reader may rely on
        the type."""
        if not all(isinstance(kind, SolidKind) for kind in self.kinds):
            msgspec.structs.force_setattr(self, "kinds", tuple(SolidKind(k) for k in self.kinds))
