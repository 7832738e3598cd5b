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

One table for both the recorder and the live Foxglove server (``modules.foxglove_live``): the same
schemas, topics and frames in a file and on a live connection.

Frames: a camera's images, its calibration and the transform tree name one frame. A
``CameraModel`` names its ``frame`` (the camera) and ``mount`` (the frame its zoom-dependent
extrinsics start from), and its ``.../mount`` view is that transform, so a viewer reaches the
camera's frame from the mount's static frame; image outputs name the same frame (DigiCam's
``camera_frame`` = CamCalib's ``camera_name``). A ``Poses`` sample holds ``T_frame_child`` of every
child in chain order (the message's meaning); written as a chain, each child in the one before,
so a viewer draws the arm link by link rather than a star from its base. Read back, the chain is
composed again (a star from older recordings reads back too).

Protobuf classes and schemas come from ``foxglove-schemas-protobuf`` (the schema is the class's
FileDescriptorSet, as ``mcap-protobuf-support`` builds it); JSON schemas from
``runtime.recording.json_codec``. No channel has an empty schema.

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
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.JointState_pb2 import JointState as FoxgloveJoint
from foxglove_schemas_protobuf.JointStates_pb2 import JointStates
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from google.protobuf.message import DecodeError as ProtobufDecodeError
from google.protobuf.timestamp_pb2 import Timestamp
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from connectors.image_header import check_image_size
from connectors.messages import CameraModel, Contour, Image, JointState, Message, Pose, Poses
from runtime.recording.json_codec import decode_json, encode_json, json_schema

IMAGE_FORMATS = ("raw", "jpeg", "png")
#: The joint of a ``foxglove.JointStates`` message that carries ``JointState.gripper`` (0..1).
GRIPPER_JOINT = "gripper"
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


def wall_offset(now: float) -> float:
    """Wall-clock time minus the run's clock [s], read once at ``now`` (the run's clock) when a
    recording or live server starts: every time it writes is the run's time plus this."""
    return time.time() - now


def time_ns(seconds: float, offset: float = 0.0) -> int:
    """``seconds + offset`` in whole nanoseconds, each rounded on its own (a wall-clock offset of
    ~1.8e9 s added in floating point would cost the stamp its last ~240 ns)."""
    return max(0, round(seconds * 1e9) + round(offset * 1e9))


def _stamp(seconds: float, offset: float = 0.0) -> Timestamp:
    ts = Timestamp()
    ns = time_ns(seconds, offset)
    ts.seconds, ts.nanos = divmod(ns, 1_000_000_000)
    return ts


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


# -- images ---------------------------------------------------------------------------------------
def raw_image(sample: Image, offset: float = 0.0) -> RawImage:
    """``foxglove.RawImage`` of a BGR (H x W x 3) or gray (H x W) uint8 image (time: stamp +
    ``offset`` [s])."""
    pixels = np.ascontiguousarray(sample.pixels)
    if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3):
        raise ValueError(f"images are uint8 H x W [x 3], found {pixels.dtype} {pixels.shape}")
    h, w = pixels.shape[:2]
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    encoding = {1: "mono8", 3: "bgr8"}.get(channels)
    if encoding is None:
        raise ValueError(f"images have 1 or 3 channels, found {channels}")
    return RawImage(
        timestamp=_stamp(sample.stamp, offset),
        frame_id=sample.frame,
        width=w,
        height=h,
        encoding=encoding,
        step=w * channels,
        data=pixels.tobytes(),
    )


def compressed_image(
    sample: Image, fmt: str, jpeg_quality: int, offset: float = 0.0
) -> CompressedImage:
    """``foxglove.CompressedImage`` (``jpeg`` or ``png``) encoded by OpenCV."""
    if fmt == "jpeg":
        ok, buf = cv2.imencode(".jpg", sample.pixels, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
    else:
        ok, buf = cv2.imencode(".png", sample.pixels, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {sample.pixels.shape} image as {fmt}")
    return CompressedImage(
        timestamp=_stamp(sample.stamp, offset),
        frame_id=sample.frame,
        data=buf.tobytes(),
        format=fmt,
    )


# -- poses ----------------------------------------------------------------------------------------
def frame_transform(
    parent: str, child: str, T_parent_child: np.ndarray, stamp: float, offset: float = 0.0
) -> Any:
    """``foxglove.FrameTransform``: pose of ``child`` in ``parent`` (m, quaternion x y z w) at
    ``stamp + offset`` [s]."""
    T = np.asarray(T_parent_child, dtype=float)
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    ft = FrameTransform(
        timestamp=_stamp(stamp, offset), parent_frame_id=parent, child_frame_id=child
    )
    ft.translation.x, ft.translation.y, ft.translation.z = (float(v) for v in T[:3, 3])
    ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w = float(x), float(y), float(z), w
    return ft


def frame_transforms(
    static: list[tuple[str, str, np.ndarray]], stamp: float, offset: float = 0.0
) -> FrameTransforms:
    """``foxglove.FrameTransforms`` of frames ``(parent, child, T_parent_child)``: the graph's
    static frames, or the frames of one ``Poses`` sample."""
    return FrameTransforms(
        transforms=[frame_transform(p, c, T, stamp, offset) for p, c, T in static]
    )


def _pose(sample: Pose, offset: float = 0.0) -> Any:
    return frame_transform(sample.parent, sample.child, sample.matrix, sample.stamp, offset)


def poses_chain(sample: Poses) -> list[tuple[str, str, np.ndarray]]:
    """``(parent, child, T_parent_child)`` of a ``Poses`` sample as a chain: its first child in
    ``frame``, each next child in the one before (``T_frame_children[i]`` composed back)."""
    matrices = np.asarray(sample.matrices, dtype=float).reshape(-1, 4, 4)
    if len(matrices) != len(sample.children):
        raise ValueError(
            f"Poses holds {len(matrices)} matrices for {len(sample.children)} children"
        )
    chain = []
    parent, T_frame_parent = sample.frame, np.eye(4)
    for child, T_frame_child in zip(sample.children, matrices, strict=True):
        chain.append((parent, child, np.linalg.solve(T_frame_parent, T_frame_child)))
        parent, T_frame_parent = child, T_frame_child
    return chain


def _poses(sample: Poses, offset: float = 0.0) -> FrameTransforms:
    return frame_transforms(poses_chain(sample), sample.stamp, offset)


def joint_states(sample: JointState, offset: float = 0.0) -> JointStates:
    """``foxglove.JointStates``: each joint's position [rad or m] and velocity (when the sample
    has one per joint), then the gripper's opening (0 closed .. 1 open) as joint ``gripper``."""
    position = np.asarray(sample.position, dtype=float).reshape(-1)
    velocity = np.asarray(sample.velocity, dtype=float).reshape(-1)
    names = tuple(sample.names)
    if len(position) != len(names) or velocity.size not in (0, len(names)):
        raise ValueError(
            f"JointState holds {len(position)} positions and {velocity.size} velocities "
            f"for {len(names)} joints"
        )
    if GRIPPER_JOINT in names:
        raise ValueError(f"joint name `{GRIPPER_JOINT}` is kept for the gripper's opening")
    out = JointStates(timestamp=_stamp(sample.stamp, offset))
    for i, name in enumerate(names):
        joint = FoxgloveJoint(name=name, position=float(position[i]))
        if velocity.size:
            joint.velocity = float(velocity[i])
        out.joints.append(joint)
    out.joints.append(FoxgloveJoint(name=GRIPPER_JOINT, position=float(sample.gripper)))
    return out


def _matrix(ft: Any) -> np.ndarray:
    """T_parent_child (4 x 4) of a ``foxglove.FrameTransform``."""
    T = np.eye(4)
    q = ft.rotation
    T[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    T[:3, 3] = [ft.translation.x, ft.translation.y, ft.translation.z]
    if not np.isfinite(T).all():
        raise ValueError(f"transform {ft.parent_frame_id}->{ft.child_frame_id} is not finite")
    return T


# -- views ----------------------------------------------------------------------------------------
_GREEN = Color(r=0.1, g=0.9, b=0.2, a=1.0)
_RED = Color(r=1.0, g=0.2, b=0.1, a=1.0)
_WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)
_SHADE = Color(r=0.0, g=0.0, b=0.0, a=0.6)


def contour_annotations(sample: Contour, offset: float = 0.0) -> ImageAnnotations:
    """The snake drawn on its image: outline (green tracking, red failed), centroid, status."""
    stamp = _stamp(sample.stamp, offset)
    color = _GREEN if sample.status == "tracking" else _RED
    out = ImageAnnotations()
    vertices = np.asarray(sample.vertices, dtype=float).reshape(-1, 2)
    if len(vertices):
        out.points.append(
            PointsAnnotation(
                timestamp=stamp,
                type=PointsAnnotation.LINE_LOOP,
                points=[Point2(x=float(u), y=float(v)) for u, v in vertices],
                outline_color=color,
                thickness=2.0,
            )
        )
    centroid = np.asarray(sample.centroid, dtype=float).reshape(-1)
    if centroid.size == 2 and np.isfinite(centroid).all():
        u, v = float(centroid[0]), float(centroid[1])
        out.points.append(
            PointsAnnotation(
                timestamp=stamp,
                type=PointsAnnotation.LINE_LIST,
                points=[
                    Point2(x=u - 6, y=v),
                    Point2(x=u + 6, y=v),
                    Point2(x=u, y=v - 6),
                    Point2(x=u, y=v + 6),
                ],
                outline_color=color,
                thickness=1.5,
            )
        )
    text = sample.status + (f": {sample.reason}" if sample.reason else "")
    out.texts.append(
        TextAnnotation(
            timestamp=stamp,
            position=Point2(x=8, y=20),
            text=text,
            font_size=16,
            text_color=_WHITE,
            background_color=_SHADE,
        )
    )
    return out


def camera_calibration(sample: CameraModel, offset: float = 0.0) -> CameraCalibration:
    """``foxglove.CameraCalibration``: K, OpenCV's plumb-bob distortion, P = [K | 0]."""
    K = sample.K
    P = np.hstack([K, np.zeros((3, 1))])
    return CameraCalibration(
        timestamp=_stamp(sample.stamp, offset),
        frame_id=sample.frame,
        width=int(sample.width),
        height=int(sample.height),
        distortion_model="plumb_bob",
        D=[float(d) for d in np.asarray(sample.dist).reshape(-1)],
        K=[float(v) for v in K.reshape(-1)],
        R=[float(v) for v in np.eye(3).reshape(-1)],
        P=[float(v) for v in P.reshape(-1)],
    )


def camera_mount(sample: CameraModel, offset: float = 0.0) -> Any:
    """``foxglove.FrameTransform`` mount → camera frame (``T_mount_camera``, zoom-dependent), or
    None when the model names one frame for both."""
    if not sample.mount or not sample.frame or sample.mount == sample.frame:
        return None
    return frame_transform(sample.mount, sample.frame, sample.T_mount_camera, sample.stamp, offset)


def view_frames(sample: Message) -> list[tuple[str, str]]:
    """``(parent, child)`` of every transform the encodings of ``sample`` write."""
    if isinstance(sample, Pose):
        return [(sample.parent, sample.child)]
    if isinstance(sample, Poses):
        return [(p, c) for p, c, _T in poses_chain(sample)]
    if isinstance(sample, CameraModel) and (ft := camera_mount(sample)) is not None:
        return [(ft.parent_frame_id, ft.child_frame_id)]
    return []


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
        return [_protobuf(FrameTransform, "", partial(_pose, offset=offset))]
    if issubclass(msg_type, Poses):
        return [_protobuf(FrameTransforms, "", partial(_poses, offset=offset))]
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
#: The message type each Foxglove schema of a primary channel is read back as.
_SCHEMA_CARRIES: dict[str, type[Message]] = {
    "foxglove.RawImage": Image,
    "foxglove.CompressedImage": Image,
    "foxglove.FrameTransform": Pose,
    "foxglove.FrameTransforms": Poses,
    "foxglove.JointStates": JointState,
}


def decode_primary(msg_type: type[Message], schema_name: str, data: bytes, seq: int) -> Message:
    """The sample of ``msg_type`` on a primary channel with ``schema_name``; ValueError when the
    bytes are not one (``seq``: the MCAP message's sequence number, the sample's ``seq``)."""
    carried = _SCHEMA_CARRIES.get(schema_name)
    if schema_name.startswith("umbra."):
        carried_name = schema_name.removeprefix("umbra.")
        if carried_name != msg_type.__name__:
            raise ValueError(
                f"schema {schema_name} carries {carried_name}, not {msg_type.__name__}"
            )
    elif carried is not None and not issubclass(msg_type, carried):
        raise ValueError(
            f"schema {schema_name} carries {carried.__name__}, not {msg_type.__name__}"
        )
    try:
        if schema_name == "foxglove.RawImage":
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
            return msg_type(
                pixels=pixels, frame=raw.frame_id, stamp=_seconds(raw.timestamp), seq=seq
            )
        if schema_name == "foxglove.CompressedImage":
            comp = CompressedImage.FromString(data)
            width, height = check_image_size(comp.data)  # before decoding: as the decoder reads it
            pixels = cv2.imdecode(np.frombuffer(comp.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
            if pixels is None:
                raise ValueError(f"{comp.format or 'compressed'} image does not decode")
            if pixels.shape[:2] != (height, width):
                raise ValueError(
                    f"image decodes to {pixels.shape[1]} x {pixels.shape[0]} pixels, its header "
                    f"declares {width} x {height}"
                )
            return msg_type(
                pixels=pixels, frame=comp.frame_id, stamp=_seconds(comp.timestamp), seq=seq
            )
        if schema_name == "foxglove.FrameTransform":
            ft = FrameTransform.FromString(data)
            return msg_type(
                matrix=_matrix(ft),
                parent=ft.parent_frame_id,
                child=ft.child_frame_id,
                stamp=_seconds(ft.timestamp),
                seq=seq,
            )
        if schema_name == "foxglove.FrameTransforms":
            return _decode_poses(msg_type, FrameTransforms.FromString(data), seq)
        if schema_name == "foxglove.JointStates":
            return _decode_joints(msg_type, JointStates.FromString(data), seq)
    except ProtobufDecodeError as exc:
        raise ValueError(f"not a {schema_name} message: {exc}") from None
    if schema_name.startswith("umbra."):
        return decode_json(msg_type, data)
    raise ValueError(f"no reader for schema {schema_name!r}")


#: The most frames one recorded ``Poses`` sample may hold (an arm has a few; a header cannot make
#: a reader build millions of matrices).
MAX_POSES = 1024


def _decode_poses(msg_type: type[Message], fts: FrameTransforms, seq: int) -> Message:
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
            T = T @ _matrix(t)
            matrices.append(T)
    elif set(parents) == {frame}:
        matrices = [_matrix(t) for t in transforms]
    else:
        raise ValueError(
            f"FrameTransforms of one Poses sample form a chain or share a parent, found "
            f"parents {parents} for {list(children)}"
        )
    return msg_type(
        matrices=np.stack(matrices),
        children=children,
        frame=frame,
        stamp=_seconds(transforms[0].timestamp),
        seq=seq,
    )


def _decode_joints(msg_type: type[Message], js: JointStates, seq: int) -> Message:
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
        stamp=_seconds(js.timestamp),
        seq=seq,
    )


def _seconds(ts: Timestamp) -> float:
    return ts.seconds + ts.nanos * 1e-9
