"""ROS 2 messages as umbra's, for graph inputs that take a ROS 2 topic.

A message's ``header.stamp`` becomes the sample's ``stamp`` and ``origin`` on the run clock
(:func:`umbra.runtime.ros2.stamps.from_stamp`: the origin moved towards the past by the stated
error bound, ``-inf`` when the stamp cannot be related). Sizes are checked before anything is
allocated or decoded, against the limits every image reader keeps
(``umbra.connectors.limits``).

=================================  ============  ===========================================
ROS 2                              umbra         how
=================================  ============  ===========================================
sensor_msgs/msg/Image              Image         bgr8, rgb8, bgra8, rgba8, mono8 -> BGR uint8
sensor_msgs/msg/CompressedImage    Image         JPEG or PNG, size read from its header first
sensor_msgs/msg/JointState         JointState    the mapping's joints (else every name) in
                                                 its order, velocities when given, the
                                                 gripper joint's position as the opening
geometry_msgs/msg/PolygonStamped   Contour       vertices (x, y) [px], with their moments
=================================  ============  ===========================================

A contour's features (centroid, area, orientation, axes) are the polygon's exact area moments as
OpenCV computes them (``cv2.moments``, Green's theorem, as ``umbra.modules.vision.features``
does; ``tests/ros2/test_inbound_contour.py`` holds the two equal), so a ROS 2 simulator's ground
truth outline can stand for DigiCam's ``truth``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from umbra.connectors.image_header import check_image_size
from umbra.connectors.limits import MAX_IMAGE_SIDE_PX, MAX_RECORDING_RECORD_BYTES
from umbra.connectors.messages import Contour, Image, JointState, Message
from umbra.connectors.tracking import TrackStatus
from umbra.runtime.ros2.stamps import Dated, WallRelation, from_stamp


@dataclass(frozen=True)
class InOptions:
    """What a mapping adds to a conversion: ``frame_id`` (when the message names none) and
    ``clock_error_s`` [s], the bound of the sender's wall clock against ours."""

    frame_id: str = ""
    clock_error_s: float = 0.0
    joints: tuple[str, ...] = ()
    gripper_joint: str = ""


#: Channels and the OpenCV conversion to BGR (the name of its ``cv2`` code: OpenCV loads when
#: a first image comes) of each raw image encoding taken.
_ENCODINGS: dict[str, tuple[int, str | None]] = {
    "bgr8": (3, None),
    "rgb8": (3, "COLOR_RGB2BGR"),
    "bgra8": (4, "COLOR_BGRA2BGR"),
    "rgba8": (4, "COLOR_RGBA2BGR"),
    "mono8": (1, "COLOR_GRAY2BGR"),
}


def dated(msg: Any, rel: WallRelation, opts: InOptions) -> Dated:
    """The run-clock stamp and origin of a message's ``header.stamp``."""
    return from_stamp(
        int(msg.header.stamp.sec), int(msg.header.stamp.nanosec), rel, opts.clock_error_s
    )


def _check_side(width: int, height: int) -> None:
    if not (0 < width <= MAX_IMAGE_SIDE_PX and 0 < height <= MAX_IMAGE_SIDE_PX):
        raise ValueError(
            f"expected image sides 1..{MAX_IMAGE_SIDE_PX} px, found {width} x {height}"
        )


def image(msg: Any, rel: WallRelation, opts: InOptions) -> Image:
    """A ``sensor_msgs/Image`` as a BGR image; ValueError for an encoding or size not taken."""
    import cv2

    if msg.encoding not in _ENCODINGS:
        raise ValueError(
            f"expected an image encoding among {', '.join(_ENCODINGS)}, found {msg.encoding!r}"
        )
    channels, conversion = _ENCODINGS[msg.encoding]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    _check_side(w, h)
    if step < w * channels or len(msg.data) < step * h:
        raise ValueError(
            f"expected {h} rows of at least {w * channels} bytes, found step {step} and"
            f" {len(msg.data)} bytes"
        )
    rows = np.asarray(msg.data, dtype=np.uint8)[: step * h].reshape(h, step)
    raw = rows[:, : w * channels].reshape(h, w, channels)
    if conversion is None:
        pixels = raw.copy()
    else:  # cv2's stubs type its result loosely: a uint8 image gives a uint8 image
        pixels = np.asarray(cv2.cvtColor(raw, getattr(cv2, conversion)), dtype=np.uint8)
    d = dated(msg, rel, opts)
    return Image(
        pixels=pixels,
        frame=msg.header.frame_id or opts.frame_id or "camera",
        stamp=d.stamp_s,
        origin=d.origin_s,
    )


def compressed_image(msg: Any, rel: WallRelation, opts: InOptions) -> Image:
    """A ``sensor_msgs/CompressedImage`` (JPEG or PNG) as a BGR image; its declared size is
    checked before it is decoded."""
    import cv2

    data = np.asarray(msg.data, dtype=np.uint8)
    w, h = check_image_size(data.tobytes())
    pixels = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if pixels is None or pixels.shape[:2] != (h, w):
        raise ValueError(
            f"expected a decodable {w} x {h} image, found {msg.format!r} bytes that are not"
        )
    d = dated(msg, rel, opts)
    return Image(
        pixels=pixels,
        frame=msg.header.frame_id or opts.frame_id or "camera",
        stamp=d.stamp_s,
        origin=d.origin_s,
    )


def joint_state(msg: Any, rel: WallRelation, opts: InOptions) -> JointState:
    """A ``sensor_msgs/JointState`` as umbra's: the mapping's ``joints`` in their order (every
    name in the message's order when it names none; ValueError when one is missing), velocities
    when the message gives one per name, and the ``gripper_joint``'s position as the gripper's
    opening (0 closed .. 1 open)."""
    names = tuple(str(n) for n in msg.name)
    position = np.asarray(msg.position, dtype=np.float64)
    if position.size != len(names):
        raise ValueError(f"expected {len(names)} positions (one per name), found {position.size}")
    velocity = np.asarray(msg.velocity, dtype=np.float64)
    if velocity.size not in (0, len(names)):
        raise ValueError(f"expected 0 or {len(names)} velocities, found {velocity.size}")
    index = {n: i for i, n in enumerate(names)}
    gripper = 0.0
    if opts.gripper_joint:
        if opts.gripper_joint not in index:
            raise ValueError(f"expected gripper joint {opts.gripper_joint!r}, found {list(names)}")
        gripper = float(np.clip(position[index[opts.gripper_joint]], 0.0, 1.0))
    wanted = opts.joints or tuple(n for n in names if n != opts.gripper_joint)
    missing = [n for n in wanted if n not in index]
    if missing:
        raise ValueError(f"expected joints {list(wanted)}, found {list(names)}")
    order = [index[n] for n in wanted]
    d = dated(msg, rel, opts)
    return JointState(
        names=tuple(wanted),
        position=position[order].copy(),
        velocity=velocity[order].copy() if velocity.size else velocity.copy(),
        gripper=gripper,
        stamp=d.stamp_s,
        origin=d.origin_s,
    )


def contour(msg: Any, rel: WallRelation, opts: InOptions) -> Contour:
    """A ``geometry_msgs/PolygonStamped`` (vertices ``(x, y)`` [px] in the image, ``z`` unused) as
    a Contour with the polygon's moment features; ``idle`` (no features) when it has fewer than 3
    vertices or no area."""
    import cv2

    vertices = np.array([(p.x, p.y) for p in msg.polygon.points], dtype=np.float64).reshape(-1, 2)
    d = dated(msg, rel, opts)
    m = cv2.moments(vertices.astype(np.float32)) if len(vertices) >= 3 else {"m00": 0.0}
    if abs(m["m00"]) <= 0.0:
        return Contour(
            vertices=vertices, centroid=np.zeros(0), area=0.0, orientation=0.0,
            axes=np.zeros(0), status=TrackStatus.IDLE, reason="no polygon",
            stamp=d.stamp_s, origin=d.origin_s,
        )  # fmt: skip
    area = abs(m["m00"])
    mu20, mu11, mu02 = (m[k] / m["m00"] for k in ("mu20", "mu11", "mu02"))
    half_trace, spread = 0.5 * (mu20 + mu02), float(np.hypot(0.5 * (mu20 - mu02), mu11))
    orientation = float(0.5 * np.arctan2(2.0 * mu11, mu20 - mu02))
    if orientation <= -np.pi / 2:
        orientation += np.pi
    axes = 4.0 * np.sqrt(np.maximum([half_trace + spread, half_trace - spread], 0.0))
    return Contour(
        vertices=vertices,
        centroid=np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]]),
        area=float(area),
        orientation=orientation,
        axes=axes,
        status=TrackStatus.TRACKING,
        stamp=d.stamp_s,
        origin=d.origin_s,
    )


Converter = Callable[[Any, WallRelation, InOptions], Message]

#: (ROS 2 message type, umbra message type) -> its converter, for inputs taken from ROS 2.
INBOUND: dict[tuple[str, str], Converter] = {
    ("sensor_msgs/msg/Image", "Image"): image,
    ("sensor_msgs/msg/CompressedImage", "Image"): compressed_image,
    ("sensor_msgs/msg/JointState", "JointState"): joint_state,
    ("geometry_msgs/msg/PolygonStamped", "Contour"): contour,
}

#: Largest payload taken of an image type [bytes]: a raw image of the largest side at 4 bytes a
#: pixel, with room for its header (what a recording's record may hold).
MAX_IMAGE_PAYLOAD_BYTES = MAX_RECORDING_RECORD_BYTES
#: Largest payload taken of any other type [bytes].
MAX_OTHER_PAYLOAD_BYTES = 1 << 20
_IMAGE_TYPES = frozenset({"sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"})


def max_payload_bytes(ros_type: str) -> int:
    """Largest CDR payload of ``ros_type`` decoded [bytes]; a larger one is refused unread."""
    return MAX_IMAGE_PAYLOAD_BYTES if ros_type in _IMAGE_TYPES else MAX_OTHER_PAYLOAD_BYTES
