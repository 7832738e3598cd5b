"""CamCalib and Targeting modules through the public harness."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.messages import Pose, Vector, ZoomState
from umbra.modules.calib.camcalib import REPORT_FILE, CamCalib
from umbra.modules.calib.camera_message import camera_message, pinhole_from_message
from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.rotations import invert_transform, rotation_from_vector, transform
from umbra.modules.calib.targeting import Targeting
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.modules.calib.zoom_table import ZoomFile
from umbra.modules.calib.zoom_yaml import write_zoom_yaml
from umbra.runtime.harness import ModuleHarness


def test_camcalib_publishes_model_at_zoom_and_only_on_change() -> None:
    table = load_zoom_table(REPORT_FILE)
    with ModuleHarness(CamCalib, {"mount_frame": "tool"}) as h:
        h.push("zoom", ZoomState(zoom=0.125))
        sent = h.step(0.1)
        model = sent["camera"][0]
        assert model.fx == pytest.approx((1004.12 + 1208.51) / 2)
        assert model.zoom == 0.125 and model.mount == "tool" and model.frame == "camera"
        expected = table.sample(0.125).camera()
        np.testing.assert_allclose(
            model.T_mount_camera, invert_transform(transform(expected.R, expected.d))
        )
        # Same zoom again: no recomputation, nothing sent.
        h.push("zoom", ZoomState(zoom=0.125, moving=False))
        assert "camera" not in h.step(0.1)
        # Unknown zoom (NaN before the first VISCA reply) is ignored.
        h.push("zoom", ZoomState(zoom=float("nan"), status="starting"))
        assert "camera" not in h.step(0.1)
        h.push("zoom", ZoomState(zoom=1.0))
        assert h.step(0.1)["camera"][0].fx == 29600.0
        assert h.module.summary() == {"models_computed": 2, "zoom_clamped": 0, "zoom_unknown": 1}


def test_camcalib_clamps_outside_table(tmp_path) -> None:
    table = load_zoom_table(REPORT_FILE)
    short = type(table)("zcam", table.zooms[:6], table.intrinsics[:6], table.extrinsics[:6])
    path = tmp_path / "short.yaml"
    write_zoom_yaml(path, ZoomFile((short,)))
    with ModuleHarness(CamCalib, {"calibration_file": str(path)}) as h:
        h.push("zoom", ZoomState(zoom=0.9))
        model = h.step(0.1)["camera"][0]
        assert model.fx == table.intrinsics[5, 0] and model.zoom == 0.3
        assert h.module.summary()["zoom_clamped"] == 1


def test_camcalib_bad_file_is_a_user_error(tmp_path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<SR_world>\n<SR_cam> x\n</SR_cam>\n</SR_world>\n")
    with pytest.raises(UserError, match=r"bad.xml:2: error: camera 'x' has no <SR_zoom>"):
        ModuleHarness(CamCalib, {"calibration_file": str(bad)}).start()


def stereo_models():
    K = Intrinsics(900.0, 900.0, 0.0, 320.0, 240.0)
    dist = np.array([-0.1, 0.05, 0.0, 0.0])
    # Camera a at x = -0.2 m and b at x = +0.3 m of the base, both toward +z, toed in.
    cams = []
    for x, yaw in ((-0.2, 0.1), (0.3, -0.15)):
        R = rotation_from_vector([0.0, yaw, 0.0]).T
        centre = np.array([x, 0.0, 0.0])
        cams.append(PinholeCamera(K, R, -R @ centre, dist))
    return cams


def test_targeting_triangulates_through_static_frames() -> None:
    cam_a, cam_b = stereo_models()
    target = np.array([0.05, -0.1, 2.0])
    # Mount frames 'ptu_a', 'ptu_b' offset in the base; models relative to the mounts.
    T_base_ptu_a = transform(rotation_from_vector([0, 0, 0.2]), [0.1, 0.0, 0.05])
    T_base_ptu_b = transform(np.eye(3), [-0.05, 0.02, 0.0])
    models = []
    for cam, T_base_mount, mount in (
        (cam_a, T_base_ptu_a, "ptu_a"),
        (cam_b, T_base_ptu_b, "ptu_b"),
    ):
        relative = cam.with_extrinsic_matrix(cam.extrinsic_matrix() @ T_base_mount)
        models.append(camera_message(relative, mount=mount))
    frames = {"base->ptu_a": T_base_ptu_a, "base->ptu_b": T_base_ptu_b}
    with ModuleHarness(Targeting, {"reference_frame": "base"}, frames=frames) as h:
        h.push("camera_a", models[0])
        h.push("camera_b", models[1])
        h.push("pixel_a", Vector(values=cam_a.project(target)))
        h.push("pixel_b", Vector(values=cam_b.project(target)))
        sent = h.step(0.1)
        np.testing.assert_allclose(sent["point"][0].values, target, atol=1e-9)
        assert sent["gap"][0].value < 1e-9
        assert sent["status"][0].stage == "ok"
        # A mismatched pixel pair: a large gap, reported as a mismatch.
        h.push("pixel_b", Vector(values=cam_b.project(target) + np.array([0.0, 25.0])))
        sent = h.step(0.1)
        assert sent["gap"][0].value > 0.01
        assert sent["status"][0].stage == "mismatch"


def test_targeting_with_moving_mount_pose_and_errors() -> None:
    cam_a, cam_b = stereo_models()
    target = np.array([-0.1, 0.05, 1.5])
    T_base_head = transform(rotation_from_vector([0.0, 0.3, 0.0]), [0.0, 0.5, 0.0])
    on_head = cam_a.with_extrinsic_matrix(cam_a.extrinsic_matrix() @ T_base_head)
    with ModuleHarness(Targeting, {"method": "linear"}) as h:
        h.push("camera_a", camera_message(on_head, mount="head"))
        h.push("camera_b", camera_message(cam_b, mount="base"))
        h.push("mount_pose_a", Pose(matrix=T_base_head, parent="base", child="head"))
        h.push("pixel_a", Vector(values=cam_a.project(target)))
        h.push("pixel_b", Vector(values=cam_b.project(target)))
        np.testing.assert_allclose(h.step(0.1)["point"][0].values, target, atol=1e-9)
        # The mount pose names the wrong frames: an error status, no point.
        h.push("mount_pose_a", Pose(matrix=T_base_head, parent="world", child="head"))
        h.push("pixel_a", Vector(values=cam_a.project(target)))
        sent = h.step(0.1)
        assert "point" not in sent and sent["status"][0].stage == "error"
        assert "expected base->head" in sent["status"][0].reason
    # No static frame from base to the camera's mount.
    with ModuleHarness(Targeting, {}) as h:
        h.push("camera_a", camera_message(cam_a, mount="nowhere"))
        h.push("camera_b", camera_message(cam_b, mount="base"))
        h.push("pixel_a", Vector(values=cam_a.project(target)))
        h.push("pixel_b", Vector(values=cam_b.project(target)))
        sent = h.step(0.1)
        assert sent["status"][0].stage == "error" and "nowhere" in sent["status"][0].reason


def test_message_round_trip() -> None:
    cam, _ = stereo_models()
    back = pinhole_from_message(camera_message(cam, zoom=0.3))
    np.testing.assert_allclose(back.camera_matrix(), cam.camera_matrix(), atol=1e-12)
    np.testing.assert_allclose(back.distortion, cam.distortion)


def test_extrinsic_matrix_round_trip() -> None:
    cam, _ = stereo_models()
    T = cam.extrinsic_matrix()
    np.testing.assert_array_equal(T[:3, :3], cam.R)
    np.testing.assert_array_equal(T[:3, 3], cam.d)
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])
    T_moved = transform(rotation_from_vector([0.1, -0.2, 0.3]), [0.5, -0.1, 0.2])
    moved = cam.with_extrinsic_matrix(T_moved)
    np.testing.assert_array_equal(moved.extrinsic_matrix(), T_moved)
    assert moved.intrinsics == cam.intrinsics
    np.testing.assert_array_equal(moved.distortion, cam.distortion)
