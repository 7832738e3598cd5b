"""Recordings a ROS 2 user opens (``--record-format ros2``): every channel ``ros2msg``/``cdr``,
as ``ros2 bag`` writes MCAP, so rosbags and ``ros2 bag`` read the file without a plug-in.

Each output is written as the ROS 2 message the ROS 2 bridge publishes for it
(``umbra.runtime.ros2.outbound``: one table for the wire and the file); images recorded as
``jpeg`` or ``png`` become ``sensor_msgs/msg/CompressedImage`` (encoded as the Foxglove
recordings encode them); a camera model's calibration is its primary channel and its mount a
``/mount`` view (``tf2_msgs/msg/TFMessage``); a type with no ROS 2 counterpart is written as
``std_msgs/msg/String`` holding the JSON of ``umbra.runtime.recording.json_codec``. The graph's
static frames go to ``/tf_static``.

``header.stamp`` is the sample's origin on the wall clock, moved by the recording's one clock
offset (wall − the run's clock, taken when the recording starts), the offset every other time in
the file is moved by.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from umbra.connectors.messages import CameraModel, Image, Message, Pose
from umbra.runtime.recording.encoders import ChannelEncoding
from umbra.runtime.recording.foxglove_msgs import compressed_image
from umbra.runtime.recording.json_codec import encode_json
from umbra.runtime.ros2.msgtypes import definition_text, message_class, to_cdr
from umbra.runtime.ros2.outbound import OUTBOUND, OutOptions, header, tf_message
from umbra.runtime.ros2.stamps import WallRelation

ROS2MSG = "ros2msg"
CDR = "cdr"
STRING = "std_msgs/msg/String"
TF = "tf2_msgs/msg/TFMessage"

#: The ROS 2 type each umbra type is recorded as (its primary channel).
RECORDED_AS: dict[str, str] = {
    "JointState": "sensor_msgs/msg/JointState",
    "Pose": TF,
    "Poses": TF,
    "CameraModel": "sensor_msgs/msg/CameraInfo",
    "Image": "sensor_msgs/msg/Image",
    "Contour": "geometry_msgs/msg/PolygonStamped",
    "Status": "diagnostic_msgs/msg/DiagnosticArray",
    "Twist": "geometry_msgs/msg/TwistStamped",
    "JointRates": "std_msgs/msg/Float64MultiArray",
}


def relation(offset: float) -> WallRelation:
    """The recording's clock relation: wall = run + ``offset`` [s], no error."""
    return WallRelation(run_s=0.0, offset_ns=round(offset * 1e9), error_ns=0)


def _channel(ros_type: str, suffix: str, encode: Any) -> ChannelEncoding:
    return ChannelEncoding(
        suffix=suffix,
        schema_name=ros_type,
        schema_encoding=ROS2MSG,
        schema_data=definition_text(ros_type).encode(),
        message_encoding=CDR,
        encode=lambda sample: to_cdr(encode(sample), ros_type),
    )


def _converted(umbra_type: str, ros_type: str, rel: WallRelation, sample: Message) -> Any:
    return OUTBOUND[(umbra_type, ros_type)](sample, rel, OutOptions())


def _json_string(sample: Message) -> Any:
    return message_class(STRING)(data=encode_json(sample).decode())


def _compressed(fmt: str, jpeg_quality: int, rel: WallRelation, sample: Image) -> Any:
    comp = compressed_image(sample, fmt, jpeg_quality)
    return message_class("sensor_msgs/msg/CompressedImage")(
        header=header(sample, sample.frame, rel, OutOptions()),
        format=fmt,
        data=np.frombuffer(comp.data, dtype=np.uint8),
    )


def ros2_channel_encodings(
    msg_type: type[Message], images: str = "raw", jpeg_quality: int = 90, offset: float = 0.0
) -> list[ChannelEncoding]:
    """The channels of ``msg_type`` in a ROS 2 recording (primary first), as
    ``umbra.runtime.recording.encoders.channel_encodings`` gives them for a Foxglove one."""
    rel = relation(offset)
    name = next((c.__name__ for c in msg_type.__mro__ if c.__name__ in RECORDED_AS), None)
    if name is None:
        return [_channel(STRING, "", _json_string)]
    if name == "Image" and images != "raw":
        ros_type = "sensor_msgs/msg/CompressedImage"
        return [_channel(ros_type, "", partial(_compressed, images, jpeg_quality, rel))]
    primary = _channel(RECORDED_AS[name], "", partial(_converted, name, RECORDED_AS[name], rel))
    if issubclass(msg_type, CameraModel):
        return [primary, _channel(TF, "/mount", partial(_converted, name, TF, rel))]
    return [primary]


def static_frames_message(
    frames: list[tuple[str, str, Any]], now: float, offset: float
) -> tuple[ChannelEncoding, bytes]:
    """The ``/tf_static`` channel and its one message for the graph's static frames
    ``(parent, child, T_parent_child)`` at run time ``now`` [s]."""
    rel = relation(offset)
    transforms = [
        tf_message(Pose(matrix=T, parent=p, child=c, origin=now), rel, OutOptions()).transforms[0]
        for p, c, T in frames
    ]
    channel = _channel(TF, "", lambda msg: msg)
    return channel, to_cdr(message_class(TF)(transforms=transforms), TF)
