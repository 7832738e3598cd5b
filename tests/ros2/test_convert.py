"""umbra's messages to ROS 2 and back, through CDR, decoded by rosbags; stamps on the wall clock."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.connectors.messages import (
    CameraModel,
    Contour,
    Image,
    JointRates,
    JointState,
    Pose,
    Poses,
    Status,
    Twist,
)
from umbra.runtime.ros2.inbound import INBOUND, InOptions
from umbra.runtime.ros2.msgtypes import from_cdr, message_class, to_cdr
from umbra.runtime.ros2.outbound import OUTBOUND, OutOptions
from umbra.runtime.ros2.stamps import WallRelation, from_stamp, relate, to_stamp

#: wall = run + 1.7e9 s exactly, measured with a 200 ns error
REL = WallRelation(run_s=1000.0, offset_ns=1_700_000_000 * 10**9, error_ns=200)


def through_cdr(umbra_type: str, ros_type: str, sample, opts: OutOptions | None = None):
    msg = OUTBOUND[(umbra_type, ros_type)](sample, REL, opts or OutOptions())
    return from_cdr(to_cdr(msg, ros_type), ros_type)


def test_joint_state_with_origin_as_stamp_and_gripper_joint():
    sample = JointState(
        names=("j1", "j2"),
        position=np.array([0.1, -0.2]),
        velocity=np.array([0.01, 0.02]),
        gripper=0.75,
        origin=999.25,
        stamp=999.5,
    )
    got = through_cdr(
        "JointState", "sensor_msgs/msg/JointState", sample, OutOptions(gripper_joint="grip")
    )
    assert got.name == ["j1", "j2", "grip"]
    np.testing.assert_array_equal(got.position, [0.1, -0.2, 0.75])
    np.testing.assert_array_equal(got.velocity, [0.01, 0.02, 0.0])
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == (1_700_000_999, 250_000_000)


def test_undatable_origin_goes_out_as_stamp_zero():
    for origin in (-math.inf, 0.0):
        sample = JointState(names=("j1",), position=np.zeros(1), origin=origin)
        got = through_cdr("JointState", "sensor_msgs/msg/JointState", sample)
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == (0, 0)


def test_poses_as_tf_with_quaternions():
    rot = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix()
    m1 = np.eye(4)
    m1[:3, :3] = rot
    m1[:3, 3] = [0.5, -0.25, 1.0]
    sample = Poses(
        matrices=np.stack([np.eye(4), m1]),
        children=("link1", "flange"),
        frame="base",
        origin=1000.0,
    )
    got = through_cdr("Poses", "tf2_msgs/msg/TFMessage", sample)
    assert [t.child_frame_id for t in got.transforms] == ["link1", "flange"]
    assert {t.header.frame_id for t in got.transforms} == {"base"}
    t = got.transforms[1].transform
    assert (t.translation.x, t.translation.y, t.translation.z) == (0.5, -0.25, 1.0)
    q = [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w]
    np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), rot, atol=1e-12)
    one = through_cdr(
        "Pose", "tf2_msgs/msg/TFMessage", Pose(matrix=m1, parent="tool", child="camera")
    )
    assert (one.transforms[0].header.frame_id, one.transforms[0].child_frame_id) == (
        "tool",
        "camera",
    )


def test_camera_model_as_camera_info_and_tf():
    cam = CameraModel(
        fx=800.0,
        fy=810.0,
        skew=0.5,
        u0=320.0,
        v0=240.0,
        dist=np.array([0.1, -0.05, 0.001, 0.002, 0.01]),
        width=640,
        height=480,
        frame="wrist_camera",
        mount="tool",
        origin=1000.5,
    )
    info = through_cdr("CameraModel", "sensor_msgs/msg/CameraInfo", cam)
    assert (info.width, info.height, info.distortion_model, info.header.frame_id) == (
        640,
        480,
        "plumb_bob",
        "wrist_camera",
    )
    np.testing.assert_array_equal(info.k, [800.0, 0.5, 320.0, 0.0, 810.0, 240.0, 0.0, 0.0, 1.0])
    np.testing.assert_array_equal(
        info.p, [800.0, 0.5, 320.0, 0.0, 0.0, 810.0, 240.0, 0.0, 0, 0, 1, 0]
    )
    np.testing.assert_array_equal(info.d, cam.dist)
    tf = through_cdr("CameraModel", "tf2_msgs/msg/TFMessage", cam)
    assert (tf.transforms[0].header.frame_id, tf.transforms[0].child_frame_id) == (
        "tool",
        "wrist_camera",
    )


def test_image_out_and_back():
    rng = np.random.default_rng(1)
    pixels = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
    sample = Image(pixels=pixels, frame="wrist_camera", origin=1000.0, stamp=1000.0)
    msg = through_cdr("Image", "sensor_msgs/msg/Image", sample)
    assert (msg.encoding, msg.height, msg.width, msg.step) == ("bgr8", 48, 64, 192)
    back = INBOUND[("sensor_msgs/msg/Image", "Image")](msg, REL, InOptions())
    np.testing.assert_array_equal(back.pixels, pixels)
    assert back.frame == "wrist_camera"
    assert back.stamp == pytest.approx(1000.0, abs=1e-9)
    assert back.origin == pytest.approx(1000.0 - 200e-9, abs=1e-9)  # moved by the error bound


def _ros_image(encoding: str, pixels: np.ndarray, pad: int = 0):
    cls = message_class("sensor_msgs/msg/Image")
    h, w = pixels.shape[:2]
    rows = pixels.reshape(h, -1)
    step = rows.shape[1] + pad
    data = np.zeros((h, step), np.uint8)
    data[:, : rows.shape[1]] = rows
    header = message_class("std_msgs/msg/Header")(
        stamp=message_class("builtin_interfaces/msg/Time")(sec=1_700_000_999, nanosec=0),
        frame_id="",
    )
    return cls(
        header=header,
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=step,
        data=data.reshape(-1),
    )


@pytest.mark.parametrize("encoding", ["rgb8", "rgba8", "mono8", "bgra8"])
def test_image_encodings_in_with_padded_rows(encoding):
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 10, 20, 30
    if encoding == "mono8":
        src, expect = np.full((4, 5), 77, np.uint8), np.full((4, 5, 3), 77, np.uint8)
    else:
        src = cv2.cvtColor(
            bgr,
            {"rgb8": cv2.COLOR_BGR2RGB, "rgba8": cv2.COLOR_BGR2RGBA, "bgra8": cv2.COLOR_BGR2BGRA}[
                encoding
            ],
        )
        expect = bgr
    msg = from_cdr(
        to_cdr(_ros_image(encoding, src, pad=3), "sensor_msgs/msg/Image"), "sensor_msgs/msg/Image"
    )
    got = INBOUND[("sensor_msgs/msg/Image", "Image")](msg, REL, InOptions(frame_id="cam"))
    np.testing.assert_array_equal(got.pixels, expect)
    assert got.frame == "cam"
    assert got.stamp == pytest.approx(999.0, abs=1e-9)


@pytest.mark.parametrize(
    "encoding, height, why",
    [("16UC1", 4, "encoding among"), ("bgr8", 0, "sides 1..8192"), ("bgr8", 9000, "sides 1..8192")],
)
def test_images_refused_say_why(encoding, height, why):
    msg = _ros_image("bgr8", np.zeros((4, 5, 3), np.uint8))
    msg.encoding, msg.height = encoding, height
    with pytest.raises(ValueError, match=why):
        INBOUND[("sensor_msgs/msg/Image", "Image")](msg, REL, InOptions())


def test_short_image_data_is_refused():
    msg = _ros_image("bgr8", np.zeros((4, 5, 3), np.uint8))
    msg.data = msg.data[:-1]
    with pytest.raises(ValueError, match="expected 4 rows of at least 15 bytes"):
        INBOUND[("sensor_msgs/msg/Image", "Image")](msg, REL, InOptions())


def test_compressed_image_in_and_a_lying_header_refused():
    bgr = np.zeros((30, 40, 3), np.uint8)
    bgr[:, :20] = (255, 0, 0)
    ok, png = cv2.imencode(".png", bgr)
    assert ok
    header = message_class("std_msgs/msg/Header")(
        stamp=message_class("builtin_interfaces/msg/Time")(sec=0, nanosec=0), frame_id="cam"
    )
    cls = message_class("sensor_msgs/msg/CompressedImage")
    got = INBOUND[("sensor_msgs/msg/CompressedImage", "Image")](
        cls(header=header, format="png", data=png.reshape(-1)), REL, InOptions()
    )
    np.testing.assert_array_equal(got.pixels, bgr)
    assert got.origin == -math.inf  # stamp zero: cannot be related
    huge = bytearray(png.tobytes())
    huge[16:24] = (20000).to_bytes(4, "big") * 2  # IHDR says 20000 x 20000
    with pytest.raises(ValueError):
        INBOUND[("sensor_msgs/msg/CompressedImage", "Image")](
            cls(header=header, format="png", data=np.frombuffer(bytes(huge), np.uint8)),
            REL,
            InOptions(),
        )


def test_joint_state_in_checks_lengths():
    cls = message_class("sensor_msgs/msg/JointState")
    header = message_class("std_msgs/msg/Header")(
        stamp=message_class("builtin_interfaces/msg/Time")(sec=1_700_000_999, nanosec=500_000_000),
        frame_id="",
    )
    msg = cls(
        header=header,
        name=["a", "b"],
        position=np.array([1.0, 2.0]),
        velocity=np.zeros(0),
        effort=np.zeros(0),
    )
    got = INBOUND[("sensor_msgs/msg/JointState", "JointState")](
        msg, REL, InOptions(clock_error_s=0.002)
    )
    assert got.names == ("a", "b") and got.velocity.size == 0
    assert got.stamp == pytest.approx(999.5, abs=1e-9)
    assert got.origin == pytest.approx(999.5 - 0.002 - 200e-9, abs=1e-9)
    msg.position = np.array([1.0])
    with pytest.raises(ValueError, match="expected 2 positions"):
        INBOUND[("sensor_msgs/msg/JointState", "JointState")](msg, REL, InOptions())


def test_contour_status_and_commands():
    contour = Contour(
        vertices=np.array([[10.0, 20.0], [30.5, 20.0], [30.5, 40.0]]),
        centroid=np.array([20.0, 30.0]),
        area=200.0,
        orientation=0.0,
        axes=np.array([20.0, 10.0]),
        origin=1000.0,
    )
    poly = through_cdr(
        "Contour", "geometry_msgs/msg/PolygonStamped", contour, OutOptions(frame_id="wrist_camera")
    )
    assert [(p.x, p.y, p.z) for p in poly.polygon.points] == [
        (10, 20, 0),
        (30.5, 20, 0),
        (30.5, 40, 0),
    ]
    assert poly.header.frame_id == "wrist_camera"
    status = Status(
        stage="approach",
        message="lost the patch",
        assist=True,
        reason="snake_failed",
        values={"ex": 1.5},
    )
    diag = through_cdr(
        "Status", "diagnostic_msgs/msg/DiagnosticArray", status, OutOptions(status_name="servo")
    )
    s = diag.status[0]
    assert (s.level, s.name, s.message) == (1, "servo", "lost the patch")
    assert {kv.key: kv.value for kv in s.values} == {
        "stage": "approach",
        "assist": "true",
        "reason": "snake_failed",
        "ex": "1.5",
    }
    twist = Twist(vector=np.array([0.01, 0.02, 0.03, 0.1, 0.2, 0.3]), frame="tool", origin=1000.0)
    ts = through_cdr("Twist", "geometry_msgs/msg/TwistStamped", twist)
    assert ts.header.frame_id == "tool"
    assert (ts.twist.linear.z, ts.twist.angular.x) == (0.03, 0.1)
    rates = JointRates(names=("j1", "j2", "j3"), rates=np.array([0.1, -0.2, 0.3]))
    arr = through_cdr("JointRates", "std_msgs/msg/Float64MultiArray", rates)
    np.testing.assert_array_equal(arr.data, [0.1, -0.2, 0.3])
    assert (arr.layout.dim[0].label, arr.layout.dim[0].size) == ("joints", 3)


def test_wall_relation_and_stamps():
    rel = relate()
    assert 0 <= rel.error_ns < 1_000_000  # two wall reads a millisecond apart at worst
    sec, nanosec = to_stamp(rel.run_s, rel)
    back = from_stamp(sec, nanosec, rel, 0.0)
    assert back.stamp_s == pytest.approx(rel.run_s, abs=2e-9)
    assert from_stamp(sec + 10, nanosec, rel, 1.0).origin_s == -math.inf  # 10 s in the future
    assert from_stamp(sec + 1, nanosec, rel, 2.0).origin_s == pytest.approx(
        rel.run_s + 1 - 2.0 - rel.error_ns * 1e-9
    )
    assert from_stamp(0, 0, rel, 0.0).origin_s == -math.inf
    assert from_stamp(sec, 1_000_000_000, rel, 0.0).origin_s == -math.inf
