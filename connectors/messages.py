"""Message types: small immutable records with numpy payloads.

Every sample carries ``stamp`` (seconds on the run's clock: the time the data describes, e.g. the
instant a frame was exposed), ``seq`` (per-output sequence number, filled in by the output port)
and ``origin`` (seconds, same clock: the capture time of the oldest sensor data the sample was
derived from; the output port fills it in, see ``umbra.connectors.ports``). A command computed now
from a 30-second-old image has a fresh ``stamp`` and an ``origin`` 30 s old: guards judge the
origin. Units are SI: metres, radians, seconds. Arrays are numpy arrays; treat them as read-only.

Frame-bearing types say so with ``FRAME_KIND``: a ``Twist`` is expressed in one frame (``frame``);
a ``Pose`` relates a parent and a child frame. Joint vectors carry joint ``names`` so that the
Jacobian, the velocity register and the joint driver agree on the arm's joints and their order.
"""

from __future__ import annotations

import functools
import importlib
import logging
from importlib.metadata import entry_points
from typing import ClassVar

import msgspec
import numpy as np

from umbra.connectors.tracking import SnakeCheck, TrackStatus

#: Entry-point group through which another package adds message types: each entry point names a
#: module (``[project.entry-points."umbra.messages"]`` ``widgets = "widget_msgs"``) whose
#: :class:`Message` subclasses every process then knows by class name.
MESSAGE_GROUP = "umbra.messages"
#: The base layer's other modules of message types (typed states and commands; the vocabulary
#: several domains speak: Active Sketch's, a planned path's, a PTU's, a simulated scene's),
#: imported with this one by :func:`message_types`: every process knows their types as it knows
#: these.
CORE_MESSAGE_MODULES = (
    "umbra.connectors.states",
    "umbra.connectors.commands",
    "umbra.connectors.sketch_messages",
    "umbra.connectors.path_messages",
    "umbra.connectors.ptu_messages",
    "umbra.connectors.scene_messages",
)

_EMPTY = np.zeros(0)
_F8 = "float64"


class Message(msgspec.Struct, frozen=True, kw_only=True):
    """Base of every message: sample time ``stamp`` [s], sequence number ``seq`` and ``origin``
    [s], the capture time of the oldest sensor data behind the sample (0: not set yet, filled in
    when sent; ``-inf``: cannot be dated, which every guard treats as old)."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "stamp": "s, the run's clock: the time the data describes (e.g. exposure)",
        "seq": "per-output sequence number, 1, 2, 3... (0: never sent)",
        "origin": "s, same clock as `stamp`: capture time of the oldest sensor data the "
        "sample derives from (0: not set; -inf: cannot be dated, treat as old)",
    }

    stamp: float = 0.0
    seq: int = 0
    origin: float = 0.0

    #: "frame" (one frame in ``frame``), "pose" (``parent`` -> ``child``) or "" (no frame).
    FRAME_KIND: ClassVar[str] = ""
    #: True when the message carries joint ``names``.
    HAS_JOINTS: ClassVar[bool] = False


class Scalar(Message, frozen=True, kw_only=True):
    """One number, in the unit its producer documents."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "value": "the unit its producer documents",
    }

    value: float


class Vector(Message, frozen=True, kw_only=True):
    """A vector of numbers, in the unit its producer documents."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "values": f"{_F8} (N,), the unit its producer documents",
    }

    values: np.ndarray = _EMPTY


class Text(Message, frozen=True, kw_only=True):
    """A line of text: operator commands (``resume``, ``abort``, ``seed 320,240``), log lines."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "text": "UTF-8 text: an operator command or a log line",
    }

    text: str


class Image(Message, frozen=True, kw_only=True):
    """A camera frame: ``pixels`` H x W x 3 uint8 in BGR order (OpenCV's), in camera ``frame``.

    ``stale`` is set when the source stopped delivering and this is the last good frame again.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "pixels": "uint8 (H, W, 3), BGR order, row-major",
        "frame": "camera frame name",
        "stale": "true: the source stopped; this is its last good frame again",
    }

    pixels: np.ndarray
    frame: str = "camera"
    stale: bool = False


class Contour(Message, frozen=True, kw_only=True):
    """A tracked closed contour in image coordinates (pixels; u right, v down).

    ``vertices`` N x 2; ``centroid`` [u, v]; ``area`` [px²]; ``orientation`` [rad] principal-axis
    angle from the u axis; ``axes`` [major, minor] axis lengths [px]. ``status`` is "tracking",
    "failed" or "idle" (:class:`~umbra.connectors.tracking.TrackStatus`); ``checks`` are the codes
    of the checks that failed and ``reason`` says why in exact words (figures included);
    ``offending`` are the indices of vertices that broke a sanity check.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "vertices": f"{_F8} (N, 2), px (u right, v down)",
        "centroid": f"{_F8} (2,), px [u, v]",
        "area": "px²",
        "orientation": "rad, principal axis from the u axis",
        "axes": f"{_F8} (2,), px [major, minor]",
        "status": '"tracking", "failed" or "idle"',
        "reason": "why tracking failed, in exact words",
        "offending": "int or float (K,), indices of vertices that broke a check",
        "checks": "codes of the failed checks (SnakeCheck), in the order found",
    }

    vertices: np.ndarray
    centroid: np.ndarray
    area: float
    orientation: float
    axes: np.ndarray
    status: TrackStatus = TrackStatus.TRACKING
    reason: str = ""
    offending: np.ndarray = _EMPTY
    checks: tuple[SnakeCheck, ...] = ()


class Twist(Message, frozen=True, kw_only=True):
    """A spatial velocity [vx, vy, vz, wx, wy, wz] (m/s, rad/s) expressed in ``frame``."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "vector": f"{_F8} (6,), [vx, vy, vz] m/s then [wx, wy, wz] rad/s",
        "frame": "frame the twist is expressed in",
    }

    vector: np.ndarray
    frame: str

    FRAME_KIND: ClassVar[str] = "frame"


class Pose(Message, frozen=True, kw_only=True):
    """Rigid transform ``matrix`` (4 x 4, m): pose of ``child`` in ``parent``, T_parent_child."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "matrix": f"{_F8} (4, 4), m: T_parent_child",
        "parent": "frame name",
        "child": "frame name",
    }

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

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "matrices": f"{_F8} (N, 4, 4), m: T_frame_children[i]",
        "children": "N frame names",
        "frame": "parent frame of every matrix",
    }

    matrices: np.ndarray
    children: tuple[str, ...]
    frame: str

    FRAME_KIND: ClassVar[str] = "frame"


class JointState(Message, frozen=True, kw_only=True):
    """Joint positions [rad or m] and velocities [rad/s or m/s], one per joint in ``names``."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "names": "N joint names, in the order of the arrays",
        "position": f"{_F8} (N,), rad (revolute) or m (prismatic)",
        "velocity": f"{_F8} (N,) or (0,), rad/s or m/s",
        "gripper": "opening, 0 closed .. 1 open",
    }

    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray = _EMPTY
    gripper: float = 0.0  #: gripper opening, 0 closed .. 1 open

    HAS_JOINTS: ClassVar[bool] = True


class JointRates(Message, frozen=True, kw_only=True):
    """Commanded joint rates [rad/s or m/s], one per joint in ``names``; flags from the solver."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "names": "N joint names",
        "rates": f"{_F8} (N,), commanded rad/s or m/s",
        "near_singularity": "solver flag",
        "near_limit": "solver flag",
    }

    names: tuple[str, ...]
    rates: np.ndarray
    near_singularity: bool = False
    near_limit: bool = False

    HAS_JOINTS: ClassVar[bool] = True


#: A device's ``status`` when nothing is wrong (``ZoomState``, ``PtuState``); any other status
#: says what is wrong, in words for a person.
DEVICE_OK = "ok"


class ZoomState(Message, frozen=True, kw_only=True):
    """Zoom of a zoom camera: normalized ``zoom`` 0 (wide) .. 1 (tele), ``raw`` device units."""

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "zoom": "0 wide .. 1 tele",
        "raw": "device units",
        "moving": "true while zooming",
        "status": f'"{DEVICE_OK}" or what is wrong',
    }

    zoom: float
    raw: int = 0
    moving: bool = False
    status: str = DEVICE_OK

    @property
    def ok(self) -> bool:
        """Nothing is wrong with the zoom camera (its ``status`` is ``DEVICE_OK``)."""
        return self.status == DEVICE_OK


class CameraModel(Message, frozen=True, kw_only=True):
    """A calibrated pinhole camera with OpenCV's distortion model.

    Intrinsics in pixels: ``fx``, ``fy``, ``skew``, principal point ``u0``, ``v0``; distortion
    ``dist`` = [k1, k2, p1, p2, k3]; image ``width`` x ``height`` [px]. ``T_mount_camera`` (4 x 4,
    metres) is the camera's pose in its mount frame (``mount``), and ``frame`` names the camera.
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "fx": "px",
        "fy": "px",
        "skew": "px",
        "u0": "px, principal point",
        "v0": "px, principal point",
        "dist": f"{_F8} (5,), OpenCV [k1, k2, p1, p2, k3]",
        "width": "px",
        "height": "px",
        "T_mount_camera": f"{_F8} (4, 4), m: the camera in `mount`",
        "mount": "frame name",
        "frame": "camera frame name",
        "zoom": "0 wide .. 1 tele, the zoom these intrinsics hold at",
    }

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
    """A module's state for a person: ``stage``, a ``message``, and whether it asks for help.

    ``assist`` is True when the operator's assistance is requested; ``reason`` says why.
    ``values`` carries named figures (errors, counters) for display and logs. Free text, for
    people and displays: a state other modules decide on is a typed one
    (``umbra.connectors.states``).
    """

    #: What each field holds on the wire (unit, dtype and shape): ``docs/wire-format.md``.
    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "stage": "the module's stage",
        "message": "for the operator",
        "assist": "true: the operator's help is requested",
        "reason": "why help is requested",
        "values": "map str -> float: named figures",
    }

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

    FIELD_NOTES: ClassVar[dict[str, str]] = {
        "module": "module instance name, as in the graph",
        "param": "parameter name (declared tunable)",
        "value": "JSON text: the new value",
        "old": "JSON text: the value it replaced (empty: a request)",
        "by": "who asked: a viewer's label",
    }

    module: str
    param: str
    value: str
    old: str = ""
    by: str = ""


@functools.cache
def plugin_message_modules() -> tuple[str, ...]:
    """Import the base layer's other message modules and those the ``umbra.messages`` entry
    points name (once per process) and return the entry points' module names; one that fails to
    import is left out with a warning (its types stay unknown, and samples of them are refused as
    of an unknown type)."""
    for name in CORE_MESSAGE_MODULES:
        importlib.import_module(name)
    loaded = []
    for ep in sorted(entry_points(group=MESSAGE_GROUP), key=lambda e: e.name):
        try:
            module = ep.load()
        except Exception as exc:  # a broken plug-in must not stop a reader of the others
            logging.getLogger("umbra").warning(
                "message types of entry point %s = %s not loaded: %s", ep.name, ep.value, exc
            )
            continue
        loaded.append(module.__name__)
    return tuple(loaded)


def message_types() -> dict[str, type[Message]]:
    """All message types by class name (the names used in YAML, ``describe`` and the wire):
    those of the base layer, those of the ``umbra.messages`` entry points (imported here, so that a
    process that never imported them, a recording's reader or a relay, still knows them) and
    any other subclass imported so far."""
    plugin_message_modules()
    found: dict[str, type[Message]] = {}
    stack: list[type[Message]] = [Message]
    while stack:
        cls = stack.pop()
        for sub in cls.__subclasses__():
            found[sub.__name__] = sub
            stack.append(sub)
    return found


def registered_message_types() -> dict[str, type[Message]]:
    """The message types that ship: those of the base layer and of the ``umbra.messages`` entry
    points (not a subclass a test or a script defines on its own), by class name."""
    homes = {__name__, *CORE_MESSAGE_MODULES, *plugin_message_modules()}
    return {n: c for n, c in message_types().items() if c.__module__ in homes}
