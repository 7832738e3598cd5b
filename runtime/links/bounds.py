"""The largest sample a link may carry [bytes], from its message type and its producer.

A receiving link drops anything larger before decoding it (``ZenohTransport``), so a flood of huge
samples costs the consumer a length check each, never a copy or a decode. The bound is the encoded
size of the largest legitimate sample plus room for the envelope and strings:

* fixed-size types (``Twist``, ``Pose``, ``Scalar``, ``ZoomState``, ``CameraModel``, the typed
  states and commands...): their arrays and texts plus ``ENVELOPE_BYTES`` (a Twist is ~100 bytes
  on the wire; its bound is 1 KiB);
* joint vectors: ``MAX_JOINTS`` joints;
* ``Image``: the producer's declared frame size (its ``width``/``height`` parameters, e.g. a
  DigiCam's) at ``IMAGE_BYTES_PER_PIXEL`` bytes per pixel, else ``DEFAULT_IMAGE_PIXELS``; a type
  that carries whole images (``StereoSnapshot``: both cameras' frames, for the sketch page in a
  process of its own) as many of them, plus ``DEFAULT_MAX_BYTES`` for the rest;
* other types: ``MAX_WIRE_BYTES`` when the message class declares one, else
  ``DEFAULT_MAX_BYTES`` (message types hold small arrays; video is an ``Image``).
"""

from __future__ import annotations

from typing import Any

#: Room for the envelope (magic, version, type tag), stamps, frame names and short strings [bytes].
ENVELOPE_BYTES = 1024
#: The most joints a joint vector may carry on a link (names ~64 bytes each, two float64 each).
MAX_JOINTS = 32
#: Bytes per pixel an image may carry: up to 4 channels of uint8, or 2 of uint16.
IMAGE_BYTES_PER_PIXEL = 4
#: Pixels of an image whose producer declares no size: 4096 x 3072 (12 Mpx).
DEFAULT_IMAGE_PIXELS = 4096 * 3072
#: Framing of an image: header plus 64-byte alignment of its buffers [bytes].
IMAGE_FRAMING_BYTES = 64 * 1024
#: Bound of a message type that declares nothing (its arrays are small) [bytes].
DEFAULT_MAX_BYTES = 256 * 1024

_F8 = 8
#: Array bytes of the fixed-size types (float64 each).
_FIXED_ARRAYS = {
    "Scalar": 0,
    "Twist": 6 * _F8,
    "Pose": 16 * _F8,
    "ZoomState": 0,
    "CameraModel": (5 + 16) * _F8,
    "Text": 4096,  # operator commands and log lines: bounded text
    "GuardState": 3 * _F8 + 4096,  # travel; the exact reason
    "ServoState": 4 * (64 + _F8) + 64 * 32 + 4096,  # 4 errors, up to 64 check codes, the reason
    "Presence": 256,  # the holder's name
    "GrabCommand": 0,
    "GripperCommand": 0,
    "StopRun": 256,  # the holder's name
    "Seed": 4 * _F8,
}
#: Types that carry whole images besides small arrays: how many images.
_IMAGES = {"StereoSnapshot": 2}
#: Per-joint bytes of the joint types: a name and two values.
_PER_JOINT = {"JointState": 64 + 2 * _F8, "JointRates": 64 + _F8}


def _declared_pixels(params: Any) -> int | None:
    """``width * height`` when the producer's parameters declare a frame size (non-zero)."""
    width = getattr(params, "width", None)
    height = getattr(params, "height", None)
    if isinstance(width, int) and isinstance(height, int) and width > 0 and height > 0:
        return width * height
    return None


def max_sample_bytes(msg_type: type, producer_params: Any = None) -> int:
    """The largest encoded sample of ``msg_type`` a link accepts [bytes]; ``producer_params``
    are the parameters of the module producing it (an image's declared size)."""
    declared = getattr(msg_type, "MAX_WIRE_BYTES", None)
    if isinstance(declared, int) and declared > 0:
        return declared
    name = msg_type.__name__
    if name == "Image":
        pixels = _declared_pixels(producer_params) or DEFAULT_IMAGE_PIXELS
        return pixels * IMAGE_BYTES_PER_PIXEL + IMAGE_FRAMING_BYTES
    if name in _IMAGES:
        pixels = _declared_pixels(producer_params) or DEFAULT_IMAGE_PIXELS
        image = pixels * IMAGE_BYTES_PER_PIXEL + IMAGE_FRAMING_BYTES
        return _IMAGES[name] * image + DEFAULT_MAX_BYTES
    if name in _FIXED_ARRAYS:
        return _FIXED_ARRAYS[name] + ENVELOPE_BYTES
    if name in _PER_JOINT:
        return MAX_JOINTS * _PER_JOINT[name] + ENVELOPE_BYTES
    return DEFAULT_MAX_BYTES


#: The least zenoh message size a process accepts [bytes] (declarations, tokens, small samples).
MIN_INBOUND_BYTES = 1024 * 1024


def inbound_limit(plan: Any, process: str) -> int:
    """The largest zenoh message ``process`` of ``plan`` needs to receive [bytes]: the largest
    bound of the links it consumes, at least ``MIN_INBOUND_BYTES``. Given to zenoh as
    ``transport/link/rx/max_message_size``, it makes zenoh drop a larger message while
    reassembling it, before it holds the whole in memory (the link stays up)."""
    largest = MIN_INBOUND_BYTES
    for link in plan.links:
        if plan.modules[link.connection.dst.module].process == process:
            params = plan.modules[link.connection.src.module].params
            largest = max(largest, max_sample_bytes(link.msg_type, params) + ENVELOPE_BYTES)
    return largest
