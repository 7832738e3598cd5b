"""Message types of Active Sketch (LDRD report section 3): stereo snapshots, primitives, boxes,
macro requests.

Spoken by the sketch module, the operator's console, the 3-D view and the /sketch page, so they
live in the base layer where every domain reaches them. Units are SI (metres, radians, seconds);
poses are 4 x 4 homogeneous transforms named ``T_<parent>_<child>``; 3-D points are in the frame
named by ``frame`` (``base`` in the shipped graph). Pixel coordinates are ideal pin-hole pixels
(u right, v down) of the image named.

Flow::

    cameras + PTUs --StereoSnapshot--> sketch (operator places vertices in both images)
    sketch --SketchPrimitive / SketchBox--> 3-D view, planner
    console --MacroRequest--> planner --ToolPath--> VCR player (``path_messages``)
"""

from __future__ import annotations

from typing import ClassVar

import msgspec
import numpy as np

from umbra.connectors.messages import CameraModel, Message
from umbra.connectors.reasons import Code

_EMPTY = np.zeros(0)
_F8 = "float64"
_EMPTY2 = np.zeros((0, 2))
_EMPTY3 = np.zeros((0, 3))


class StereoSnapshot(Message, frozen=True, kw_only=True):
    """Both images and both camera models of a stereo pair at one instant (``stamp``).

    ``image_a`` / ``image_b``: H x W x 3 uint8 BGR frames of camera a (left) and b (right).
    ``K_a`` / ``K_b`` (3 x 3, px): intrinsics of each camera at the zoom it had (``zoom_a`` /
    ``zoom_b``, 0 wide .. 1 tele); ``dist_a`` / ``dist_b``: OpenCV distortion [k1, k2, p1, p2, k3].
    ``T_base_camera_a`` / ``T_base_camera_b`` (4 x 4, m): pose of each camera in ``frame`` at the
    instant (PTU angles included), so ``P = K [R | d]`` with ``[R | d]`` its inverse's top rows.
    ``snapshot_id`` names the pair; primitives placed on it carry the same id. The models are
    kept flat (not nested messages) so the compact link codec can carry them;
    :meth:`camera_model` rebuilds a :class:`~umbra.connectors.messages.CameraModel`.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "snapshot_id": "names the pair",
        "image_a": "uint8 (H, W, 3), BGR: camera a (left)",
        "image_b": "uint8 (H, W, 3), BGR: camera b (right)",
        "K_a": f"{_F8} (3, 3), px: intrinsics of camera a",
        "K_b": f"{_F8} (3, 3), px: intrinsics of camera b",
        "dist_a": f"{_F8} (5,), OpenCV distortion of camera a",
        "dist_b": f"{_F8} (5,), OpenCV distortion of camera b",
        "zoom_a": "0 wide .. 1 tele",
        "zoom_b": "0 wide .. 1 tele",
        "camera_a_name": "frame name of camera a",
        "camera_b_name": "frame name of camera b",
        "T_base_camera_a": f"{_F8} (4, 4), m: camera a in `frame`",
        "T_base_camera_b": f"{_F8} (4, 4), m: camera b in `frame`",
        "frame": "world frame of the poses",
    }

    snapshot_id: str
    image_a: np.ndarray
    image_b: np.ndarray
    K_a: np.ndarray
    K_b: np.ndarray
    dist_a: np.ndarray = np.zeros(5)
    dist_b: np.ndarray = np.zeros(5)
    zoom_a: float = 0.0
    zoom_b: float = 0.0
    camera_a_name: str = "cam_a"
    camera_b_name: str = "cam_b"
    T_base_camera_a: np.ndarray = np.eye(4)
    T_base_camera_b: np.ndarray = np.eye(4)
    frame: str = "base"

    FRAME_KIND: ClassVar[str] = "frame"

    @classmethod
    def of_pair(
        cls,
        stamp: float,
        snapshot_id: str,
        a: tuple[CameraModel, np.ndarray, np.ndarray],
        b: tuple[CameraModel, np.ndarray, np.ndarray],
        frame: str = "base",
    ) -> StereoSnapshot:
        """The pair from each camera's ``(model, image, T_frame_camera)``: intrinsics,
        distortion, zoom and name from the model, the pose [m] in ``frame``."""
        (ma, ia, Ta), (mb, ib, Tb) = a, b
        return cls(
            stamp=stamp,
            snapshot_id=snapshot_id,
            image_a=ia,
            image_b=ib,
            K_a=ma.K,
            K_b=mb.K,
            dist_a=np.asarray(ma.dist),
            dist_b=np.asarray(mb.dist),
            zoom_a=ma.zoom,
            zoom_b=mb.zoom,
            camera_a_name=ma.frame,
            camera_b_name=mb.frame,
            T_base_camera_a=Ta,
            T_base_camera_b=Tb,
            frame=frame,
        )

    def camera_model(self, side: str) -> CameraModel:
        """The model of camera ``side`` ("a" or "b"), mounted in ``frame`` at its pose."""
        if side not in ("a", "b"):
            raise ValueError(f"camera side must be 'a' or 'b', got {side!r}")
        K = np.asarray(getattr(self, f"K_{side}"), dtype=float)
        image = getattr(self, f"image_{side}")
        return CameraModel(
            stamp=self.stamp,
            fx=float(K[0, 0]),
            fy=float(K[1, 1]),
            skew=float(K[0, 1]),
            u0=float(K[0, 2]),
            v0=float(K[1, 2]),
            dist=np.asarray(getattr(self, f"dist_{side}"), dtype=float),
            width=int(image.shape[1]),
            height=int(image.shape[0]),
            T_mount_camera=np.asarray(getattr(self, f"T_base_camera_{side}"), dtype=float),
            mount=self.frame,
            frame=getattr(self, f"camera_{side}_name"),
            zoom=float(getattr(self, f"zoom_{side}")),
        )

    def camera_matrix(self, side: str) -> np.ndarray:
        """The 3 x 4 camera matrix ``K [R | d]`` of camera ``side`` (world = ``frame``)."""
        model = self.camera_model(side)
        T_camera_base = np.linalg.inv(model.T_mount_camera)
        return model.K @ T_camera_base[:3, :]


class PrimitiveKind(Code):
    """What an Active Sketch primitive is, by its vertices."""

    POINT = "point"  #: 1 vertex
    LINE = "line"  #: 2
    PLANE = "plane"  #: 3: lines a-b, b-c
    TRIAD = "triad"  #: 4: lines from vertex 0 to 1, 2, 3


class SketchReply(Code):
    """Sketch's reply to each command, the ``stage`` of its status: done (``message`` says
    what was done) or refused (``message`` and ``reason`` say why)."""

    OK = "ok"
    REFUSED = "refused"


class Macro(Code):
    """An Active Sketch motion macro (LDRD report section 3), by name. Which primitive offers
    which, what each does and the options each takes: :mod:`umbra.modules.sketch.macros`."""

    READY = "ready"
    STOW = "stow"
    MOVE_TO = "move_to"
    AIM_ALONG_RAY = "aim_along_ray"
    GRAB_PIPE = "grab_pipe"
    MOVE_AROUND_AXIS = "move_around_axis"
    APPROACH_SIDE = "approach_side"
    MOVE_PARALLEL = "move_parallel"
    AIM_ALONG_AXIS = "aim_along_axis"
    PLACE_DEVICE = "place_device"
    SURFACE_SCAN = "surface_scan"
    FOLLOW_PERIMETER = "follow_perimeter"
    MAKE_BOX = "make_box"


class SketchPrimitive(Message, frozen=True, kw_only=True):
    """A geometric primitive placed in both images of a snapshot and triangulated to 3-D.

    ``kind``: "point" (1 vertex), "line" (2), "plane" (3: two connected lines a-b, b-c, vertex b
    shared), "triad" (4: three lines from the common vertex 0 to vertices 1, 2, 3).
    ``pixels_a`` / ``pixels_b`` (N x 2, px): vertices in image a / b; each ``pixels_b[i]`` lies
    on the epipolar line of ``pixels_a[i]``. ``points`` (N x 3, m, ``frame``): triangulated
    vertices; ``covariances`` (N x 3 x 3, m²): their uncertainty from pixel noise and
    calibration; ``gaps`` (N, m): ray gaps. ``edges`` (E x 2, int): vertex index pairs drawn.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "primitive_id": "names the primitive",
        "kind": "PrimitiveKind: " + ", ".join(f'"{k}"' for k in PrimitiveKind),
        "snapshot_id": "the snapshot it was placed on",
        "pixels_a": f"{_F8} (N, 2), px in image a",
        "pixels_b": f"{_F8} (N, 2), px in image b",
        "points": f"{_F8} (N, 3), m in `frame`",
        "covariances": f"{_F8} (N, 3, 3), m²",
        "gaps": f"{_F8} (N,), m: ray gaps",
        "edges": "int64 (E, 2): vertex index pairs",
        "frame": "frame of `points`",
    }

    primitive_id: str
    kind: PrimitiveKind
    snapshot_id: str = ""
    pixels_a: np.ndarray = _EMPTY2
    pixels_b: np.ndarray = _EMPTY2
    points: np.ndarray = _EMPTY3
    covariances: np.ndarray = np.zeros((0, 3, 3))
    gaps: np.ndarray = _EMPTY
    edges: np.ndarray = np.zeros((0, 2), dtype=np.int64)
    frame: str = "base"

    FRAME_KIND: ClassVar[str] = "frame"


class SketchBox(Message, frozen=True, kw_only=True):
    """A box built from a triad (kept as scene geometry for the 3-D view).

    ``T_base_box`` (4 x 4, m): box centre and axes in ``frame``; ``size`` (3,, m): edge lengths
    along the box's x, y, z axes; ``covariance`` (3 x 3, m²) of the centre.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "box_id": "names the box",
        "T_base_box": f"{_F8} (4, 4), m: centre and axes in `frame`",
        "size": f"{_F8} (3,), m: edge lengths along x, y, z",
        "covariance": f"{_F8} (3, 3), m²: of the centre",
        "frame": "frame name",
    }

    box_id: str
    T_base_box: np.ndarray
    size: np.ndarray
    covariance: np.ndarray = np.zeros((3, 3))
    frame: str = "base"

    FRAME_KIND: ClassVar[str] = "frame"


class MacroRequest(Message, frozen=True, kw_only=True):
    """The operator's choice of a motion macro for a primitive (``primitive_id`` "" = none).

    ``macro``: one of the primitive's menu (e.g. ``Macro.GRAB_PIPE``);
    ``options``: named numbers for the macro (e.g. ``angle`` [rad], ``standoff`` [m]).
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "macro": "Macro: " + ", ".join(f'"{m}"' for m in Macro),
        "primitive_id": '"" = none',
        "options": "map str -> float (e.g. angle rad, standoff m)",
    }

    macro: Macro
    primitive_id: str = ""
    options: dict[str, float] = msgspec.field(default_factory=dict)
