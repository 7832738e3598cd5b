"""The Foxglove messages of one sample, built with the official classes (no channels, no I/O).

The builders behind ``umbra.runtime.recording.encoders``' table, for the recorder and the live
server alike: images, frame transforms (an arm's links as a chain), joint states, the snake drawn on
its image, a camera's calibration and the transform from its mount, and the time line. Every time is
``stamp + offset`` [s]: the run's clock plus one wall-clock offset (:func:`wall_offset`), each
rounded to whole nanoseconds on its own (:func:`time_ns`).
"""

from __future__ import annotations

import time
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
from google.protobuf.timestamp_pb2 import Timestamp
from scipy.spatial.transform import Rotation

from umbra.connectors.messages import CameraModel, Contour, Image, JointState, Message, Pose, Poses
from umbra.connectors.tracking import TrackStatus

#: The joint of a ``foxglove.JointStates`` message that carries ``JointState.gripper`` (0..1).
GRIPPER_JOINT = "gripper"


def wall_offset(now: float) -> float:
    """Wall-clock time minus the run's clock [s], read once at ``now`` (the run's clock) when a
    recording or live server starts: every time it writes is the run's time plus this."""
    return time.time() - now


def time_ns(seconds: float, offset: float = 0.0) -> int:
    """``seconds + offset`` in whole nanoseconds, each rounded on its own (a wall-clock offset of
    ~1.8e9 s added in floating point would cost the stamp its last ~240 ns)."""
    return max(0, round(seconds * 1e9) + round(offset * 1e9))


def timestamp_of(seconds: float, offset: float = 0.0) -> Timestamp:
    ts = Timestamp()
    ns = time_ns(seconds, offset)
    ts.seconds, ts.nanos = divmod(ns, 1_000_000_000)
    return ts


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
        timestamp=timestamp_of(sample.stamp, offset),
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
        timestamp=timestamp_of(sample.stamp, offset),
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
        timestamp=timestamp_of(stamp, offset), parent_frame_id=parent, child_frame_id=child
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


def pose_transform(sample: Pose, offset: float = 0.0) -> Any:
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


def poses_transforms(sample: Poses, offset: float = 0.0) -> FrameTransforms:
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
    out = JointStates(timestamp=timestamp_of(sample.stamp, offset))
    for i, name in enumerate(names):
        joint = FoxgloveJoint(name=name, position=float(position[i]))
        if velocity.size:
            joint.velocity = float(velocity[i])
        out.joints.append(joint)
    out.joints.append(FoxgloveJoint(name=GRIPPER_JOINT, position=float(sample.gripper)))
    return out


def matrix(ft: Any) -> np.ndarray:
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
    when = timestamp_of(sample.stamp, offset)
    color = _GREEN if sample.status == TrackStatus.TRACKING else _RED
    out = ImageAnnotations()
    vertices = np.asarray(sample.vertices, dtype=float).reshape(-1, 2)
    if len(vertices):
        out.points.append(
            PointsAnnotation(
                timestamp=when,
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
                timestamp=when,
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
            timestamp=when,
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
        timestamp=timestamp_of(sample.stamp, offset),
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


def seconds(ts: Timestamp) -> float:
    whole: int = ts.seconds  # protobuf's generated classes carry no types
    nanos: int = ts.nanos
    return whole + nanos * 1e-9
