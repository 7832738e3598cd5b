"""How each message type is written to MCAP: Foxglove's well-known schemas where one fits.

A recorded output gets one *primary* channel (topic ``/<module>/<port>``) from which the sample is
read back for replay, and for some types a *view* channel that only a viewer needs:

============  ===========================================  =======================================
type          primary channel                              view channel
============  ===========================================  =======================================
Image         ``foxglove.RawImage`` (bgr8/mono8) or        —
              ``foxglove.CompressedImage`` (jpeg, png)
Pose          ``foxglove.FrameTransform`` (parent→child)   —
Poses         ``foxglove.FrameTransforms``: a chain        —
              (frame→child 1→child 2→…, each relative
              to the one before: an arm's link frames)
JointState    ``foxglove.JointStates`` (one joint per      —
              name; the gripper's opening as a last
              joint named ``gripper``)
Contour       JSON ``umbra.Contour``                       ``.../annotations``:
                                                           ``foxglove.ImageAnnotations``
CameraModel   JSON ``umbra.CameraModel``                   ``.../calibration``:
                                                           ``foxglove.CameraCalibration``;
                                                           ``.../mount``: mount→camera frame
                                                           (``foxglove.FrameTransform``)
any other     JSON ``umbra.<Type>`` with its JSON schema   —
============  ===========================================  =======================================

One table for both the recorder and the live Foxglove server (``umbra.runtime.live``): the same
schemas, topics and frames in a file and on a live connection.

Frames: a camera's images, its calibration and the transform tree name one frame. A
``CameraModel`` names its ``frame`` (the camera) and ``mount`` (the frame its zoom-dependent
extrinsics start from), and its ``.../mount`` view is that transform, so a viewer reaches the
camera's frame from the mount's static frame; image outputs name the same frame (DigiCam's
``camera_frame`` = CamCalib's ``camera_name``). A ``Poses`` sample holds ``T_frame_child`` of every
child in chain order (the message's meaning); written as a chain, each child in the one before,
so a viewer draws the arm link by link rather than a star from its base. Read back, the chain is
composed again (a star from older recordings reads back too).

The messages are built by ``umbra.runtime.recording.foxglove_msgs``; protobuf classes and schemas
come from ``foxglove-schemas-protobuf`` (the schema is the class's
FileDescriptorSet, as ``mcap-protobuf-support`` builds it); JSON schemas from
``umbra.runtime.recording.json_codec``. No channel has an empty schema.

Time: every time written is wall-clock time, ``stamp + offset`` with one ``offset`` [s] (wall −
the run's clock) taken when the recording (or live server) starts, so a viewer's time line shows
the date and lines up with other wall-clock data; the run's own stamps stay in JSON messages'
``stamp`` field and, for every message, as its time minus the offset (a recording's metadata
``umbra.run`` holds ``clock_offset_ns``). A Foxglove image and its annotations share one
timestamp, so a viewer draws the snake on the frame it was found in. An encoder that has nothing
to write for a sample (a camera model whose mount is its own frame) returns ``b""``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any, TypeVar

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.JointStates_pb2 import JointStates
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from google.protobuf.message import DecodeError as ProtobufDecodeError
from mcap_protobuf.schema import build_file_descriptor_set

from umbra.connectors.image_header import check_image_size
from umbra.connectors.messages import CameraModel, Contour, Image, JointState, Message, Pose, Poses
from umbra.runtime.recording.foxglove_msgs import (
    GRIPPER_JOINT,
    camera_calibration,
    camera_mount,
    compressed_image,
    contour_annotations,
    joint_states,
    matrix,
    pose_transform,
    poses_transforms,
    raw_image,
    seconds,
)
from umbra.runtime.recording.json_codec import decode_json, encode_json, json_schema

IMAGE_FORMATS = ("raw", "jpeg", "png")
PROTOBUF = "protobuf"
JSON = "json"


@dataclass(frozen=True)
class ChannelEncoding:
    """One MCAP channel of a recorded output: topic suffix, schema, and the encoder."""

    suffix: str  #: "" for the primary channel, e.g. "/annotations" for a view
    schema_name: str
    schema_encoding: str  #: "protobuf" or "jsonschema"
    schema_data: bytes
    message_encoding: str  #: "protobuf" or "json"
    encode: Callable[[Message], bytes]

    @property
    def view(self) -> bool:
        return bool(self.suffix)


def _protobuf(cls: Any, suffix: str, encode: Callable[[Message], Any]) -> ChannelEncoding:
    return ChannelEncoding(
        suffix=suffix,
        schema_name=cls.DESCRIPTOR.full_name,
        schema_encoding=PROTOBUF,
        schema_data=build_file_descriptor_set(cls).SerializeToString(),
        message_encoding=PROTOBUF,
        encode=lambda sample: _serialized(encode(sample)),
    )


def _serialized(message: Any) -> bytes:
    return b"" if message is None else message.SerializeToString()


def _json(msg_type: type[Message]) -> ChannelEncoding:
    return ChannelEncoding(
        suffix="",
        schema_name=json_schema(msg_type)["title"],
        schema_encoding="jsonschema",
        schema_data=json.dumps(json_schema(msg_type)).encode(),
        message_encoding=JSON,
        encode=encode_json,
    )


# -- the table ----------------------------------------------------------------------------------
def channel_encodings(
    msg_type: type[Message], images: str = "raw", jpeg_quality: int = 90, offset: float = 0.0
) -> list[ChannelEncoding]:
    """The channels of ``msg_type`` (primary first); ``images``: raw, jpeg or png; ``offset``
    [s]: wall-clock time minus the run's clock, added to every time written."""
    if issubclass(msg_type, Image):
        if images == "raw":
            return [_protobuf(RawImage, "", partial(raw_image, offset=offset))]
        encode = partial(compressed_image, fmt=images, jpeg_quality=jpeg_quality, offset=offset)
        return [_protobuf(CompressedImage, "", encode)]
    if issubclass(msg_type, Pose):
        return [_protobuf(FrameTransform, "", partial(pose_transform, offset=offset))]
    if issubclass(msg_type, Poses):
        return [_protobuf(FrameTransforms, "", partial(poses_transforms, offset=offset))]
    if issubclass(msg_type, JointState):
        return [_protobuf(JointStates, "", partial(joint_states, offset=offset))]
    primary = _json(msg_type)
    if issubclass(msg_type, Contour):
        annotations = partial(contour_annotations, offset=offset)
        return [primary, _protobuf(ImageAnnotations, "/annotations", annotations)]
    if issubclass(msg_type, CameraModel):
        return [
            primary,
            _protobuf(
                CameraCalibration, "/calibration", partial(camera_calibration, offset=offset)
            ),
            _protobuf(FrameTransform, "/mount", partial(camera_mount, offset=offset)),
        ]
    return [primary]


# -- reading back ---------------------------------------------------------------------------------
_M = TypeVar("_M", bound=Message)


def _read_as(msg_type: type[Message], carried: type[_M], schema_name: str) -> type[_M]:
    """``msg_type``, which a primary channel with Foxglove schema ``schema_name`` is read back
    as: a ``carried`` type (ValueError when it is another)."""
    if not issubclass(msg_type, carried):
        raise ValueError(
            f"schema {schema_name} carries {carried.__name__}, not {msg_type.__name__}"
        )
    return msg_type


def decode_primary(msg_type: type[Message], schema_name: str, data: bytes, seq: int) -> Message:
    """The sample of ``msg_type`` on a primary channel with ``schema_name``; ValueError when the
    bytes are not one (``seq``: the MCAP message's sequence number, the sample's ``seq``)."""
    if schema_name.startswith("umbra."):
        carried_name = schema_name.removeprefix("umbra.")
        if carried_name != msg_type.__name__:
            raise ValueError(
                f"schema {schema_name} carries {carried_name}, not {msg_type.__name__}"
            )
    try:
        if schema_name == "foxglove.RawImage":
            image_type = _read_as(msg_type, Image, schema_name)
            raw = RawImage.FromString(data)
            channels = {"bgr8": 3, "mono8": 1}.get(raw.encoding)
            if channels is None or raw.step != raw.width * channels:
                raise ValueError(f"unsupported raw image encoding {raw.encoding!r}")
            pixel_bytes = raw.data  # a copy on every access: once
            if len(pixel_bytes) != raw.height * raw.step:
                raise ValueError(
                    f"image data holds {len(pixel_bytes)} bytes, expected {raw.height * raw.step}"
                )
            shape = (raw.height, raw.width) if channels == 1 else (raw.height, raw.width, 3)
            pixels = np.frombuffer(pixel_bytes, dtype=np.uint8).reshape(shape)
            return image_type(
                pixels=pixels, frame=raw.frame_id, stamp=seconds(raw.timestamp), seq=seq
            )
        if schema_name == "foxglove.CompressedImage":
            image_type = _read_as(msg_type, Image, schema_name)
            comp = CompressedImage.FromString(data)
            width, height = check_image_size(comp.data)  # before decoding: as the decoder reads it
            decoded = cv2.imdecode(np.frombuffer(comp.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
            if decoded is None:
                raise ValueError(f"{comp.format or 'compressed'} image does not decode")
            if decoded.shape[:2] != (height, width):
                raise ValueError(
                    f"image decodes to {decoded.shape[1]} x {decoded.shape[0]} pixels, its header "
                    f"declares {width} x {height}"
                )
            return image_type(
                pixels=decoded, frame=comp.frame_id, stamp=seconds(comp.timestamp), seq=seq
            )
        if schema_name == "foxglove.FrameTransform":
            pose_type = _read_as(msg_type, Pose, schema_name)
            ft = FrameTransform.FromString(data)
            return pose_type(
                matrix=matrix(ft),
                parent=ft.parent_frame_id,
                child=ft.child_frame_id,
                stamp=seconds(ft.timestamp),
                seq=seq,
            )
        if schema_name == "foxglove.FrameTransforms":
            poses_type = _read_as(msg_type, Poses, schema_name)
            return _decode_poses(poses_type, FrameTransforms.FromString(data), seq)
        if schema_name == "foxglove.JointStates":
            joints_type = _read_as(msg_type, JointState, schema_name)
            return _decode_joints(joints_type, JointStates.FromString(data), seq)
    except ProtobufDecodeError as exc:
        raise ValueError(f"not a {schema_name} message: {exc}") from None
    if schema_name.startswith("umbra."):
        return decode_json(msg_type, data)
    raise ValueError(f"no reader for schema {schema_name!r}")


#: The most frames one recorded ``Poses`` sample may hold (an arm has a few; a header cannot make
#: a reader build millions of matrices).
MAX_POSES = 1024


def _decode_poses(msg_type: type[Poses], fts: FrameTransforms, seq: int) -> Poses:
    """A ``Poses`` sample from ``foxglove.FrameTransforms`` of a chain (each transform's parent
    the child before it) or, as older recordings hold, a star (every transform from one frame)."""
    transforms = fts.transforms
    if not transforms or len(transforms) > MAX_POSES:
        raise ValueError(
            f"a Poses sample holds 1 to {MAX_POSES} transforms, found {len(transforms)}"
        )
    frame = transforms[0].parent_frame_id
    children = tuple(t.child_frame_id for t in transforms)
    parents = [t.parent_frame_id for t in transforms]
    if parents == [frame, *children[:-1]]:  # a chain: compose T_frame_child
        matrices, T = [], np.eye(4)
        for t in transforms:
            T = T @ matrix(t)
            matrices.append(T)
    elif set(parents) == {frame}:
        matrices = [matrix(t) for t in transforms]
    else:
        raise ValueError(
            f"FrameTransforms of one Poses sample form a chain or share a parent, found "
            f"parents {parents} for {list(children)}"
        )
    return msg_type(
        matrices=np.stack(matrices),
        children=children,
        frame=frame,
        stamp=seconds(transforms[0].timestamp),
        seq=seq,
    )


def _decode_joints(msg_type: type[JointState], js: JointStates, seq: int) -> JointState:
    """A ``JointState`` from ``foxglove.JointStates`` written by :func:`joint_states`."""
    joints = list(js.joints)
    if not joints or joints[-1].name != GRIPPER_JOINT or len(joints) > MAX_POSES:
        raise ValueError(f"JointStates end with joint `{GRIPPER_JOINT}` (at most {MAX_POSES})")
    arm = joints[:-1]
    with_velocity = [j.HasField("velocity") for j in arm]
    if any(with_velocity) and not all(with_velocity):
        raise ValueError("JointStates give a velocity for some joints but not all")
    return msg_type(
        names=tuple(j.name for j in arm),
        position=np.array([j.position for j in arm], dtype=float),
        velocity=np.array([j.velocity for j in arm], dtype=float)
        if all(with_velocity) and arm
        else np.zeros(0),
        gripper=float(joints[-1].position),
        stamp=seconds(js.timestamp),
        seq=seq,
    )
