"""``--record-format ros2``: an MCAP file whose every channel is ``ros2msg``/``cdr``, read by
rosbags' AnyReader (what ``ros2 bag`` users have) with the values and stamps we wrote."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from umbra.connectors.messages import CameraModel, Image, JointState, Scalar
from umbra.runtime.recording.writer import RecordingFile

OFFSET = 1_700_000_000.0  # wall - run [s]


def test_rosbags_reads_a_ros2_recording(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    rec = RecordingFile(path, blocking=True, clock_offset=OFFSET, record_format="ros2")
    mount = np.eye(4)
    mount[:3, 3] = [0.0, 0.05, 0.1]
    rec.write_static_frames([("world", "base", mount)], 0.0)
    rec.declare("/cam/jpeg", Image, images="jpeg")
    pixels = np.zeros((48, 64, 3), np.uint8)
    pixels[:, :32] = (0, 0, 255)
    for i in range(3):
        t = 10.0 + 0.1 * i
        js = JointState(
            names=("j1", "j2"),
            position=np.array([0.1 * i, -0.2]),
            origin=t - 0.05,
            stamp=t,
            seq=i + 1,
        )
        rec.offer("/arm/joints", js, t)
        rec.offer("/cam/image", Image(pixels=pixels, frame="cam", origin=t, stamp=t, seq=i + 1), t)
        rec.offer("/cam/jpeg", Image(pixels=pixels, frame="cam", origin=t, stamp=t, seq=i + 1), t)
        rec.offer(
            "/calib/model",
            CameraModel(
                fx=500.0,
                fy=500.0,
                u0=32.0,
                v0=24.0,
                width=64,
                height=48,
                frame="cam",
                T_mount_camera=mount,
                origin=t,
                stamp=t,
                seq=i + 1,
            ),
            t,
        )
        rec.offer("/gain/out", Scalar(value=1.5 * i, stamp=t, seq=i + 1), t)
    rec.close()
    assert rec.written == 15

    with AnyReader([path]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {
            "/tf_static": "tf2_msgs/msg/TFMessage",
            "/arm/joints": "sensor_msgs/msg/JointState",
            "/cam/image": "sensor_msgs/msg/Image",
            "/cam/jpeg": "sensor_msgs/msg/CompressedImage",
            "/calib/model": "sensor_msgs/msg/CameraInfo",
            "/calib/model/mount": "tf2_msgs/msg/TFMessage",
            "/gain/out": "std_msgs/msg/String",
        }
        got: dict[str, list] = {}
        for conn, timestamp, raw in reader.messages():
            got.setdefault(conn.topic, []).append(
                (timestamp, reader.deserialize(raw, conn.msgtype))
            )
    joints = got["/arm/joints"]
    assert [list(m.position) for _, m in joints] == [[0.0, -0.2], [0.1, -0.2], [0.2, -0.2]]
    stamp = joints[1][1].header.stamp
    assert stamp.sec + stamp.nanosec * 1e-9 == pytest.approx(OFFSET + 10.05, abs=1e-6)  # the origin
    assert joints[1][0] == pytest.approx((OFFSET + 10.1) * 1e9, abs=1e3)  # log time: the tick
    image = got["/cam/image"][0][1]
    assert (image.encoding, image.width, image.height) == ("bgr8", 64, 48)
    np.testing.assert_array_equal(np.asarray(image.data).reshape(48, 64, 3), pixels)
    jpeg = got["/cam/jpeg"][0][1]
    assert jpeg.format == "jpeg" and bytes(jpeg.data[:2]) == b"\xff\xd8"
    info = got["/calib/model"][0][1]
    assert list(info.k) == [500.0, 0.0, 32.0, 0.0, 500.0, 24.0, 0.0, 0.0, 1.0]
    tf = got["/calib/model/mount"][0][1].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.z) == (
        "tool",
        "cam",
        0.1,
    )
    static = got["/tf_static"][0][1].transforms[0]
    assert (static.header.frame_id, static.child_frame_id, static.transform.translation.y) == (
        "world",
        "base",
        0.05,
    )
    assert [json.loads(m.data)["value"] for _, m in got["/gain/out"]] == [0.0, 1.5, 3.0]


def test_an_unknown_format_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="among \\('foxglove', 'ros2'\\), found 'rosbag'"):
        RecordingFile(tmp_path / "x.mcap", record_format="rosbag")
