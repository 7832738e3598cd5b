"""How each message type is written to MCAP: Foxglove's well-known schemas where one fits.

A recorded output gets one *primary* channel (topic ``/<module>/<port>``) from which the sample is
read back for replay, and for some types a *view* channel that only a viewer needs:

============  ===========================================  =======================================
type          primary channel                              view channel
============  ===========================================  =======================================
Image         ``foxglove.RawImage`` (bgr8/mono8) or        —
              ``foxglove.CompressedImage`` (jpeg, png)
Pose          ``foxglove.FrameTransform`` (parent→child)   —
Poses         ``foxglove.FrameTransforms`` (frame→each     —
              child: an arm's link frames)
Contour       JSON ``umbra.Contour``                       ``.../annotations``:
                                                           ``foxglove.ImageAnnotations``
CameraModel   JSON ``umbra.CameraModel``                   ``.../calibration``:
                                                           ``foxglove.CameraCalibration``
any other     JSON ``umbra.<Type>`` with its JSON schema   —
============  ===========================================  =======================================

Protobuf classes and schemas come from ``foxglove-schemas-protobuf`` (the schema is the class's
FileDescriptorSet, as ``mcap-protobuf-support`` builds it); JSON schemas from
``runtime.recording.json_codec``. No channel has an empty schema. Times in the Foxglove messages
are the sample's ``stamp`` [s]; a Foxglove image and its annotations share it, so a viewer draws
the snake on the frame it was found in.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation
from google.protobuf.message import DecodeError as ProtobufDecodeError
from google.protobuf.timestamp_pb2 import Timestamp
from mcap_protobuf.schema import build_file_descriptor_set
from scipy.spatial.transform import Rotation

from connectors.image_header import check_image_size
from connectors.messages import CameraModel, Contour, Image, Message, Pose, Poses
from runtime.recording.json_codec import decode_json, encode_json, json_schema

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


def _stamp(seconds: float) -> Timestamp:
    ts = Timestamp()
    ns = max(0, round(seconds * 1e9))
    ts.seconds, ts.nanos = divmod(ns, 1_000_000_000)
    return ts


def _protobuf(cls: Any, suffix: str, encode: Callable[[Message], Any]) -> ChannelEncoding:
    return ChannelEncoding(
        suffix=suffix,
        schema_name=cls.DESCRIPTOR.full_name,
        schema_encoding=PROTOBUF,
        schema_data=build_file_descriptor_set(cls).SerializeToString(),
        message_encoding=PROTOBUF,
        encode=lambda sample: encode(sample).SerializeToString(),
    )


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
def raw_image(sample: Image) -> RawImage:
    """``foxglove.RawImage`` of a BGR (H x W x 3) or gray (H x W) uint8 image."""
    pixels = np.ascontiguousarray(sample.pixels)
    if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3):
        raise ValueError(f"images are uint8 H x W [x 3], found {pixels.dtype} {pixels.shape}")
    h, w = pixels.shape[:2]
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    encoding = {1: "mono8", 3: "bgr8"}.get(channels)
    if encoding is None:
        raise ValueError(f"images have 1 or 3 channels, found {channels}")
    return RawImage(
        timestamp=_stamp(sample.stamp),
        frame_id=sample.frame,
        width=w,
        height=h,
        encoding=encoding,
        step=w * channels,
        data=pixels.tobytes(),
    )


def compressed_image(sample: Image, fmt: str, jpeg_quality: int) -> CompressedImage:
    """``foxglove.CompressedImage`` (``jpeg`` or ``png``) encoded by OpenCV."""
    if fmt == "jpeg":
        ok, buf = cv2.imencode(".jpg", sample.pixels, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])
    else:
        ok, buf = cv2.imencode(".png", sample.pixels, [cv2.IMWRITE_PNG_COMPRESSION, 1])
    if not ok:
        raise ValueError(f"OpenCV could not encode a {sample.pixels.shape} image as {fmt}")
    return CompressedImage(
        timestamp=_stamp(sample.stamp), frame_id=sample.frame, data=buf.tobytes(), format=fmt
    )


# -- poses ----------------------------------------------------------------------------------------
def frame_transform(parent: str, child: str, T_parent_child: np.ndarray, stamp: float) -> Any:
    """``foxglove.FrameTransform``: pose of ``child`` in ``parent`` (m, quaternion x y z w)."""
    T = np.asarray(T_parent_child, dtype=float)
    x, y, z, w = Rotation.from_matrix(T[:3, :3]).as_quat()
    ft = FrameTransform(timestamp=_stamp(stamp), parent_frame_id=parent, child_frame_id=child)
    ft.translation.x, ft.translation.y, ft.translation.z = (float(v) for v in T[:3, 3])
    ft.rotation.x, ft.rotation.y, ft.rotation.z, ft.rotation.w = float(x), float(y), float(z), w
    return ft


def frame_transforms(static: list[tuple[str, str, np.ndarray]], stamp: float) -> FrameTransforms:
    """``foxglove.FrameTransforms`` of frames ``(parent, child, T_parent_child)``: the graph's
    static frames, or the frames of one ``Poses`` sample."""
    return FrameTransforms(transforms=[frame_transform(p, c, T, stamp) for p, c, T in static])


def _pose(sample: Pose) -> Any:
    return frame_transform(sample.parent, sample.child, sample.matrix, sample.stamp)


def _poses(sample: Poses) -> FrameTransforms:
    matrices = np.asarray(sample.matrices, dtype=float).reshape(-1, 4, 4)
    if len(matrices) != len(sample.children):
        raise ValueError(
            f"Poses holds {len(matrices)} matrices for {len(sample.children)} children"
        )
    return frame_transforms(
        [(sample.frame, child, T) for child, T in zip(sample.children, matrices, strict=True)],
        sample.stamp,
    )


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


def contour_annotations(sample: Contour) -> ImageAnnotations:
    """The snake drawn on its image: outline (green tracking, red failed), centroid, status."""
    stamp = _stamp(sample.stamp)
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


def camera_calibration(sample: CameraModel) -> CameraCalibration:
    """``foxglove.CameraCalibration``: K, OpenCV's plumb-bob distortion, P = [K | 0]."""
    K = sample.K
    P = np.hstack([K, np.zeros((3, 1))])
    return CameraCalibration(
        timestamp=_stamp(sample.stamp),
        frame_id=sample.frame,
        width=int(sample.width),
        height=int(sample.height),
        distortion_model="plumb_bob",
        D=[float(d) for d in np.asarray(sample.dist).reshape(-1)],
        K=[float(v) for v in K.reshape(-1)],
        R=[float(v) for v in np.eye(3).reshape(-1)],
        P=[float(v) for v in P.reshape(-1)],
    )


# -- the table ----------------------------------------------------------------------------------
def channel_encodings(
    msg_type: type[Message], images: str = "raw", jpeg_quality: int = 90
) -> list[ChannelEncoding]:
    """The channels recording ``msg_type`` (primary first); ``images``: raw, jpeg or png."""
    if issubclass(msg_type, Image):
        if images == "raw":
            return [_protobuf(RawImage, "", raw_image)]
        return [_protobuf(CompressedImage, "", lambda s: compressed_image(s, images, jpeg_quality))]
    if issubclass(msg_type, Pose):
        return [_protobuf(FrameTransform, "", _pose)]
    if issubclass(msg_type, Poses):
        return [_protobuf(FrameTransforms, "", _poses)]
    primary = _json(msg_type)
    if issubclass(msg_type, Contour):
        return [primary, _protobuf(ImageAnnotations, "/annotations", contour_annotations)]
    if issubclass(msg_type, CameraModel):
        return [primary, _protobuf(CameraCalibration, "/calibration", camera_calibration)]
    return [primary]


# -- reading back ---------------------------------------------------------------------------------
#: The message type each Foxglove schema of a primary channel is read back as.
_SCHEMA_CARRIES: dict[str, type[Message]] = {
    "foxglove.RawImage": Image,
    "foxglove.CompressedImage": Image,
    "foxglove.FrameTransform": Pose,
    "foxglove.FrameTransforms": Poses,
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
    except ProtobufDecodeError as exc:
        raise ValueError(f"not a {schema_name} message: {exc}") from None
    if schema_name.startswith("umbra."):
        return decode_json(msg_type, data)
    raise ValueError(f"no reader for schema {schema_name!r}")


#: The most frames one recorded ``Poses`` sample may hold (an arm has a few; a header cannot make
#: a reader build millions of matrices).
MAX_POSES = 1024


def _decode_poses(msg_type: type[Message], fts: FrameTransforms, seq: int) -> Message:
    """A ``Poses`` sample from ``foxglove.FrameTransforms`` that share one parent frame."""
    transforms = fts.transforms
    if not transforms or len(transforms) > MAX_POSES:
        raise ValueError(
            f"a Poses sample holds 1 to {MAX_POSES} transforms, found {len(transforms)}"
        )
    parents = {t.parent_frame_id for t in transforms}
    if len(parents) != 1:
        raise ValueError(f"FrameTransforms of one Poses sample share a parent, found {parents}")
    return msg_type(
        matrices=np.stack([_matrix(t) for t in transforms]),
        children=tuple(t.child_frame_id for t in transforms),
        frame=parents.pop(),
        stamp=_seconds(transforms[0].timestamp),
        seq=seq,
    )


def _seconds(ts: Timestamp) -> float:
    return ts.seconds + ts.nanos * 1e-9
