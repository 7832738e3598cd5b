"""Message types: small immutable records with numpy payloads.

Every sample carries ``stamp`` (seconds on the run's clock: the time the data describes, e.g. the
instant a frame was exposed), ``seq`` (per-output sequence number, filled in by the output port)
and ``origin`` (seconds, same clock: the capture time of the oldest sensor data the sample was
derived from; the output port fills it in, see ``connectors.ports``). A command computed now from
a 30-second-old image has a fresh ``stamp`` and an ``origin`` 30 s old: guards judge the origin.
Units are SI: metres, radians, seconds. Arrays are numpy arrays; treat them as read-only.

Frame-bearing types say so with ``FRAME_KIND``: a ``Twist`` is expressed in one frame (``frame``);
a ``Pose`` relates a parent and a child frame. Joint vectors carry joint ``names`` so that the
Jacobian, the velocity register and the joint driver agree on the arm's joints and their order.
"""

from __future__ import annotations

from typing import ClassVar

import msgspec
import numpy as np

_EMPTY = np.zeros(0)


class Message(msgspec.Struct, frozen=True, kw_only=True):
    """Base of every message: sample time ``stamp`` [s], sequence number ``seq`` and ``origin``
    [s], the capture time of the oldest sensor data behind the sample (0: not set yet, filled in
    when sent; ``-inf``: cannot be dated, which every guard treats as old)."""

    stamp: float = 0.0
    seq: int = 0
    origin: float = 0.0

    #: "frame" (one frame in ``frame``), "pose" (``parent`` -> ``child``) or "" (no frame).
    FRAME_KIND: ClassVar[str] = ""
    #: True when the message carries joint ``names``.
    HAS_JOINTS: ClassVar[bool] = False


class Scalar(Message, frozen=True, kw_only=True):
    """One number, in the unit its producer documents."""

    value: float


class Vector(Message, frozen=True, kw_only=True):
    """A vector of numbers, in the unit its producer documents."""

    values: np.ndarray = _EMPTY


class Text(Message, frozen=True, kw_only=True):
    """A line of text: operator commands (``resume``, ``abort``, ``seed 320,240``), log lines."""

    text: str


class Image(Message, frozen=True, kw_only=True):
    """A camera frame: ``pixels`` H x W x 3 uint8 in BGR order (OpenCV's), in camera ``frame``.

    ``stale`` is set when the source stopped delivering and this is the last good frame again.
    """

    pixels: np.ndarray
    frame: str = "camera"
    stale: bool = False


class Contour(Message, frozen=True, kw_only=True):
    """A tracked closed contour in image coordinates (pixels; u right, v down).

    ``vertices`` N x 2; ``centroid`` [u, v]; ``area`` [px²]; ``orientation`` [rad] principal-axis
    angle from the u axis; ``axes`` [major, minor] axis lengths [px]. ``status`` is "tracking",
    "failed" or "idle"; ``reason`` says why it failed; ``offending`` are the indices of vertices
    that broke a sanity check.
    """

    vertices: np.ndarray
    centroid: np.ndarray
    area: float
    orientation: float
    axes: np.ndarray
    status: str = "tracking"
    reason: str = ""
    offending: np.ndarray = _EMPTY


class Twist(Message, frozen=True, kw_only=True):
    """A spatial velocity [vx, vy, vz, wx, wy, wz] (m/s, rad/s) expressed in ``frame``."""

    vector: np.ndarray
    frame: str

    FRAME_KIND: ClassVar[str] = "frame"


class Pose(Message, frozen=True, kw_only=True):
    """Rigid transform ``matrix`` (4 x 4, m): pose of ``child`` in ``parent``, T_parent_child."""

    matrix: np.ndarray
    parent: str
    child: str

    FRAME_KIND: ClassVar[str] = "pose"


class Poses(Message, frozen=True, kw_only=True):
    """Poses of several frames in one: ``matrices[i]`` (4 x 4, m) is ``T_frame_children[i]``.

    ``matrices`` is N x 4 x 4 for the N names in ``children``: e.g. every link frame of an arm in
    its base frame (``T_base_link1`` ... ``T_base_flange``), what a viewer needs to draw the arm's
    frames.
    """

    matrices: np.ndarray
    children: tuple[str, ...]
    frame: str

    FRAME_KIND: ClassVar[str] = "frame"


class JointState(Message, frozen=True, kw_only=True):
    """Joint positions [rad or m] and velocities [rad/s or m/s], one per joint in ``names``."""

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray = _EMPTY
    gripper: float = 0.0  #: gripper opening, 0 closed .. 1 open

    HAS_JOINTS: ClassVar[bool] = True


class JointRates(Message, frozen=True, kw_only=True):
    """Commanded joint rates [rad/s or m/s], one per joint in ``names``; flags from the solver."""

    names: tuple[str, ...]
    rates: np.ndarray
    near_singularity: bool = False
    near_limit: bool = False
    gripper: str = ""  #: "", "open" or "close"

    HAS_JOINTS: ClassVar[bool] = True


class ZoomState(Message, frozen=True, kw_only=True):
    """Zoom of a zoom camera: normalized ``zoom`` 0 (wide) .. 1 (tele), ``raw`` device units."""

    zoom: float
    raw: int = 0
    moving: bool = False
    status: str = "ok"


class CameraModel(Message, frozen=True, kw_only=True):
    """A calibrated pinhole camera with OpenCV's distortion model.

    Intrinsics in pixels: ``fx``, ``fy``, ``skew``, principal point ``u0``, ``v0``; distortion
    ``dist`` = [k1, k2, p1, p2, k3]; image ``width`` x ``height`` [px]. ``T_mount_camera`` (4 x 4,
    metres) is the camera's pose in its mount frame (``mount``), and ``frame`` names the camera.
    """

    fx: float
    fy: float
    skew: float = 0.0
    u0: float
    v0: float
    dist: np.ndarray = np.zeros(5)
    width: int = 640
    height: int = 480
    T_mount_camera: np.ndarray = np.eye(4)
    mount: str = "tool"
    frame: str = "camera"
    zoom: float = 0.0

    @property
    def K(self) -> np.ndarray:
        """The 3 x 3 intrinsic matrix."""
        return np.array([[self.fx, self.skew, self.u0], [0.0, self.fy, self.v0], [0.0, 0.0, 1.0]])


class Status(Message, frozen=True, kw_only=True):
    """A module's state for the operator: ``stage``, a ``message``, and whether it asks for help.

    ``assist`` is True when the operator's assistance is requested; ``reason`` says why.
    ``values`` carries named figures (errors, counters) for display and logs.
    """

    stage: str
    message: str = ""
    assist: bool = False
    reason: str = ""
    values: dict[str, float] = msgspec.field(default_factory=dict)


class ParamChange(Message, frozen=True, kw_only=True):
    """A change of a module's tunable parameter while the graph runs (``umbra run --foxglove``).

    As a request (``old`` empty) it travels from the process that serves viewers to the process
    that runs ``module``; as a record (``old`` set) it is what that process applied, between two
    steps. ``value`` and ``old`` are JSON text (the parameter's type decides); ``by`` names who
    asked (``foxglove viewer #2 (127.0.0.1)``).
    """

    module: str
    param: str
    value: str
    old: str = ""
    by: str = ""


def message_types() -> dict[str, type[Message]]:
    """All message types by class name (the names used in YAML, ``describe`` and the wire).

    The Active Sketch types (:mod:`connectors.sketch_messages`) are imported here, so that a
    process that never imported them (a recording's reader, a relay) still knows them.
    """
    import connectors.sketch_messages  # noqa: F401 - registers its subclasses

    found: dict[str, type[Message]] = {}
    stack: list[type[Message]] = [Message]
    while stack:
        cls = stack.pop()
        for sub in cls.__subclasses__():
            found[sub.__name__] = sub
            stack.append(sub)
    return found
