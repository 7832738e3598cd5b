"""umbra's messages as ROS 2 messages (built with the distribution's rosbags classes).

Every stamped message carries the sample's ``origin`` in ``header.stamp`` (wall clock, as ROS 2
stamps are: :mod:`umbra.runtime.ros2.stamps`), so a ROS 2 consumer ages the data as our guards
do. Frames keep their names: ``header.frame_id`` is the frame a value is expressed in, and a
transform's ``child_frame_id`` the frame it places.

- JointState -> sensor_msgs/msg/JointState: names, positions [rad|m], velocities; the gripper's
  opening as one more joint when the mapping names it.
- Pose, Poses -> tf2_msgs/msg/TFMessage: one transform per child frame.
- CameraModel -> sensor_msgs/msg/CameraInfo: plumb_bob, d = [k1 k2 p1 p2 k3], K, R = I, P = [K|0].
- CameraModel -> tf2_msgs/msg/TFMessage: the camera in its mount (``T_mount_camera``).
- Image -> sensor_msgs/msg/Image: ``bgr8``, rows packed (step = 3 W).
- Contour -> geometry_msgs/msg/PolygonStamped: vertices (u, v, 0) [px] in the image's frame.
- Status -> diagnostic_msgs/msg/DiagnosticArray: one status, level WARN when help is asked;
  stage, assist, reason and the named figures as key/value pairs.
- Twist -> geometry_msgs/msg/TwistStamped: the command in its frame (as moveit_servo takes it).
- JointRates -> std_msgs/msg/Float64MultiArray: rates [rad/s] in joint order (ros2_control's
  forward velocity controller); it has no header, so no origin crosses with it.
- Text -> std_msgs/msg/String: the line as it is; no header.
- GripperCommand -> std_msgs/msg/String: the action, ``open`` or ``close``; no header.
- ServoState -> diagnostic_msgs/msg/DiagnosticArray: as a Status (it is one).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from umbra.connectors.commands import GripperCommand
from umbra.connectors.messages import (
    CameraModel,
    Contour,
    Image,
    JointRates,
    JointState,
    Message,
    Pose,
    Poses,
    Status,
    Text,
    Twist,
)
from umbra.runtime.ros2.msgtypes import message_class
from umbra.runtime.ros2.stamps import WallRelation, to_stamp


@dataclass(frozen=True)
class OutOptions:
    """What a mapping adds to a conversion: ``frame_id`` for types that name no frame (a
    contour's image frame), ``gripper_joint`` (a joint name for the gripper's opening, 0 closed ..
    1 open; empty: the gripper is left out), ``status_name`` (the DiagnosticStatus' name) and the
    ROS 2 ``distro`` whose classes build the message."""

    frame_id: str = ""
    gripper_joint: str = ""
    status_name: str = "umbra"
    distro: str = "jazzy"


def _cls(name: str, opts: OutOptions) -> Any:
    return message_class(name, opts.distro)


def header(sample: Message, frame_id: str, rel: WallRelation, opts: OutOptions) -> Any:
    """A ``std_msgs/Header`` stamped with the sample's origin (wall clock) in ``frame_id``."""
    sec, nanosec = to_stamp(sample.origin, rel)
    time_cls = _cls("builtin_interfaces/msg/Time", opts)
    return _cls("std_msgs/msg/Header", opts)(
        stamp=time_cls(sec=sec, nanosec=nanosec), frame_id=frame_id
    )


def joint_state(sample: JointState, rel: WallRelation, opts: OutOptions) -> Any:
    names = list(sample.names)
    position = np.asarray(sample.position, dtype=np.float64)
    velocity = np.asarray(sample.velocity, dtype=np.float64)
    if opts.gripper_joint:
        names.append(opts.gripper_joint)
        position = np.append(position, sample.gripper)
        if velocity.size:
            velocity = np.append(velocity, 0.0)
    return _cls("sensor_msgs/msg/JointState", opts)(
        header=header(sample, opts.frame_id, rel, opts),
        name=names,
        position=position,
        velocity=velocity,
        effort=np.zeros(0),
    )


def _transform(
    sample: Message,
    matrix: np.ndarray,
    parent: str,
    child: str,
    rel: WallRelation,
    opts: OutOptions,
) -> Any:
    from scipy.spatial.transform import Rotation  # loads with the first pose sent

    m = np.asarray(matrix, dtype=np.float64)
    x, y, z, w = Rotation.from_matrix(m[:3, :3]).as_quat()
    vec = _cls("geometry_msgs/msg/Vector3", opts)
    quat = _cls("geometry_msgs/msg/Quaternion", opts)
    transform = _cls("geometry_msgs/msg/Transform", opts)(
        translation=vec(x=float(m[0, 3]), y=float(m[1, 3]), z=float(m[2, 3])),
        rotation=quat(x=float(x), y=float(y), z=float(z), w=float(w)),
    )
    return _cls("geometry_msgs/msg/TransformStamped", opts)(
        header=header(sample, parent, rel, opts), child_frame_id=child, transform=transform
    )


def tf_message(sample: Pose | Poses | CameraModel, rel: WallRelation, opts: OutOptions) -> Any:
    """The transforms a pose, a set of poses or a camera's mounting states."""
    if isinstance(sample, Pose):
        transforms = [_transform(sample, sample.matrix, sample.parent, sample.child, rel, opts)]
    elif isinstance(sample, Poses):
        transforms = [
            _transform(sample, m, sample.frame, child, rel, opts)
            for m, child in zip(sample.matrices, sample.children, strict=True)
        ]
    else:
        transforms = [
            _transform(sample, sample.T_mount_camera, sample.mount, sample.frame, rel, opts)
        ]
    return _cls("tf2_msgs/msg/TFMessage", opts)(transforms=transforms)


def image(sample: Image, rel: WallRelation, opts: OutOptions) -> Any:
    pixels = np.ascontiguousarray(sample.pixels, dtype=np.uint8)
    if pixels.ndim != 3 or pixels.shape[2] != 3:
        raise ValueError(f"expected BGR pixels (H, W, 3), found shape {pixels.shape}")
    h, w = pixels.shape[:2]
    return _cls("sensor_msgs/msg/Image", opts)(
        header=header(sample, sample.frame, rel, opts),
        height=h,
        width=w,
        encoding="bgr8",
        is_bigendian=0,
        step=3 * w,
        data=pixels.reshape(-1),
    )


def camera_info(sample: CameraModel, rel: WallRelation, opts: OutOptions) -> Any:
    k = sample.K
    p = np.hstack([k, np.zeros((3, 1))])
    roi = _cls("sensor_msgs/msg/RegionOfInterest", opts)(
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
    )
    return _cls("sensor_msgs/msg/CameraInfo", opts)(
        header=header(sample, sample.frame, rel, opts),
        height=int(sample.height),
        width=int(sample.width),
        distortion_model="plumb_bob",
        d=np.asarray(sample.dist, dtype=np.float64).reshape(-1),
        k=k.reshape(-1).astype(np.float64),
        r=np.eye(3).reshape(-1),
        p=p.reshape(-1).astype(np.float64),
        binning_x=0,
        binning_y=0,
        roi=roi,
    )


def polygon(sample: Contour, rel: WallRelation, opts: OutOptions) -> Any:
    point = _cls("geometry_msgs/msg/Point32", opts)
    vertices = np.asarray(sample.vertices, dtype=np.float64).reshape(-1, 2)
    points = [point(x=float(u), y=float(v), z=0.0) for u, v in vertices]
    return _cls("geometry_msgs/msg/PolygonStamped", opts)(
        header=header(sample, opts.frame_id or "camera", rel, opts),
        polygon=_cls("geometry_msgs/msg/Polygon", opts)(points=points),
    )


def diagnostics(sample: Status, rel: WallRelation, opts: OutOptions) -> Any:
    status_cls = _cls("diagnostic_msgs/msg/DiagnosticStatus", opts)
    key_value = _cls("diagnostic_msgs/msg/KeyValue", opts)
    values = [
        key_value(key="stage", value=sample.stage),
        key_value(key="assist", value="true" if sample.assist else "false"),
        key_value(key="reason", value=sample.reason),
    ] + [key_value(key=k, value=repr(float(v))) for k, v in sorted(sample.values.items())]
    status = status_cls(
        level=status_cls.WARN if sample.assist else status_cls.OK,
        name=opts.status_name,
        message=sample.message or sample.stage,
        hardware_id="",
        values=values,
    )
    return _cls("diagnostic_msgs/msg/DiagnosticArray", opts)(
        header=header(sample, opts.frame_id, rel, opts), status=[status]
    )


def twist_stamped(sample: Twist, rel: WallRelation, opts: OutOptions) -> Any:
    v = np.asarray(sample.vector, dtype=np.float64).reshape(6)
    vec = _cls("geometry_msgs/msg/Vector3", opts)
    twist = _cls("geometry_msgs/msg/Twist", opts)(
        linear=vec(x=float(v[0]), y=float(v[1]), z=float(v[2])),
        angular=vec(x=float(v[3]), y=float(v[4]), z=float(v[5])),
    )
    return _cls("geometry_msgs/msg/TwistStamped", opts)(
        header=header(sample, sample.frame, rel, opts), twist=twist
    )


def float64_array(sample: JointRates, rel: WallRelation, opts: OutOptions) -> Any:
    rates = np.asarray(sample.rates, dtype=np.float64).reshape(-1)
    dim = _cls("std_msgs/msg/MultiArrayDimension", opts)(
        label="joints", size=rates.size, stride=rates.size
    )
    layout = _cls("std_msgs/msg/MultiArrayLayout", opts)(dim=[dim], data_offset=0)
    return _cls("std_msgs/msg/Float64MultiArray", opts)(layout=layout, data=rates)


def string(sample: Text, rel: WallRelation, opts: OutOptions) -> Any:
    return _cls("std_msgs/msg/String", opts)(data=sample.text)


def gripper_string(sample: GripperCommand, rel: WallRelation, opts: OutOptions) -> Any:
    return _cls("std_msgs/msg/String", opts)(data=str(sample.action))


Converter = Callable[[Any, WallRelation, OutOptions], Any]

#: (umbra message type, ROS 2 message type) -> its converter, for outputs mapped to ROS 2.
OUTBOUND: dict[tuple[str, str], Converter] = {
    ("JointState", "sensor_msgs/msg/JointState"): joint_state,
    ("Pose", "tf2_msgs/msg/TFMessage"): tf_message,
    ("Poses", "tf2_msgs/msg/TFMessage"): tf_message,
    ("CameraModel", "tf2_msgs/msg/TFMessage"): tf_message,
    ("CameraModel", "sensor_msgs/msg/CameraInfo"): camera_info,
    ("Image", "sensor_msgs/msg/Image"): image,
    ("Contour", "geometry_msgs/msg/PolygonStamped"): polygon,
    ("Status", "diagnostic_msgs/msg/DiagnosticArray"): diagnostics,
    ("ServoState", "diagnostic_msgs/msg/DiagnosticArray"): diagnostics,  # a Status
    ("Twist", "geometry_msgs/msg/TwistStamped"): twist_stamped,
    ("JointRates", "std_msgs/msg/Float64MultiArray"): float64_array,
    ("Text", "std_msgs/msg/String"): string,
    ("GripperCommand", "std_msgs/msg/String"): gripper_string,
}
