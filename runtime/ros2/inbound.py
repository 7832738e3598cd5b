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
sensor_msgs/msg/JointState         JointState    names, positions, velocities (when given)
=================================  ============  ===========================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from umbra.connectors.image_header import check_image_size
from umbra.connectors.limits import MAX_IMAGE_SIDE_PX, MAX_RECORDING_RECORD_BYTES
from umbra.connectors.messages import Image, JointState, Message
from umbra.runtime.ros2.stamps import Dated, WallRelation, from_stamp


@dataclass(frozen=True)
class InOptions:
    """What a mapping adds to a conversion: ``frame_id`` (when the message names none) and
    ``clock_error_s`` [s], the bound of the sender's wall clock against ours."""

    frame_id: str = ""
    clock_error_s: float = 0.0


#: Channels and the OpenCV conversion to BGR of each raw image encoding taken.
_ENCODINGS: dict[str, tuple[int, int | None]] = {
    "bgr8": (3, None),
    "rgb8": (3, cv2.COLOR_RGB2BGR),
    "bgra8": (4, cv2.COLOR_BGRA2BGR),
    "rgba8": (4, cv2.COLOR_RGBA2BGR),
    "mono8": (1, cv2.COLOR_GRAY2BGR),
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
    pixels = rows[:, : w * channels].reshape(h, w, channels)
    pixels = pixels.copy() if conversion is None else cv2.cvtColor(pixels, conversion)
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
    """A ``sensor_msgs/JointState`` as umbra's (positions for every name; velocities when the
    message gives one per name)."""
    names = tuple(str(n) for n in msg.name)
    position = np.asarray(msg.position, dtype=np.float64)
    if position.size != len(names):
        raise ValueError(f"expected {len(names)} positions (one per name), found {position.size}")
    velocity = np.asarray(msg.velocity, dtype=np.float64)
    if velocity.size not in (0, len(names)):
        raise ValueError(f"expected 0 or {len(names)} velocities, found {velocity.size}")
    d = dated(msg, rel, opts)
    return JointState(
        names=names,
        position=position.copy(),
        velocity=velocity.copy(),
        stamp=d.stamp_s,
        origin=d.origin_s,
    )


Converter = Callable[[Any, WallRelation, InOptions], Message]

#: (ROS 2 message type, umbra message type) -> its converter, for inputs taken from ROS 2.
INBOUND: dict[tuple[str, str], Converter] = {
    ("sensor_msgs/msg/Image", "Image"): image,
    ("sensor_msgs/msg/CompressedImage", "Image"): compressed_image,
    ("sensor_msgs/msg/JointState", "JointState"): joint_state,
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
