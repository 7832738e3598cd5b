"""Full calibration (DLT + nonlinear refinement with distortion) against truth and OpenCV."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.refine import calibrate, linear_camera, refine_camera
from umbra.modules.calib.synthetic import TYPICAL_DISTORTION, observe, panel_rig, rig_camera


@pytest.fixture
def noisy_rig() -> tuple[PinholeCamera, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(21)
    camera = rig_camera()
    points = panel_rig()
    return camera, points, observe(camera, points, 0.2, rng)


def test_exact_data_recovers_every_parameter() -> None:
    truth = rig_camera(intrinsics=Intrinsics(820.0, 815.0, 1.5, 331.0, 244.0))
    points = panel_rig()
    result = calibrate(points, truth.project(points))
    assert result.rms_px < 1e-8
    np.testing.assert_allclose(
        result.camera.intrinsics.as_array(), truth.intrinsics.as_array(), atol=1e-6
    )
    np.testing.assert_allclose(result.camera.distortion, truth.distortion, atol=1e-9)
    np.testing.assert_allclose(result.camera.R, truth.R, atol=1e-10)
    np.testing.assert_allclose(result.camera.d, truth.d, atol=1e-10)


def test_noisy_data_close_to_truth_and_to_noise_floor(noisy_rig) -> None:
    truth, points, pixels = noisy_rig
    result = calibrate(points, pixels)
    # Residual RMS of a correct fit is the noise (0.2 px per axis -> 0.28 px) less the dof.
    assert 0.2 < result.rms_px < 0.3
    assert result.linear_rms_px > 2 * result.rms_px  # the DLT cannot model distortion
    f = result.camera.intrinsics
    assert f.fx == pytest.approx(truth.intrinsics.fx, rel=0.01)
    assert f.fy == pytest.approx(truth.intrinsics.fy, rel=0.01)
    assert abs(f.u0 - truth.intrinsics.u0) < 3 and abs(f.v0 - truth.intrinsics.v0) < 3
    # k2 is weakly determined by a rig that fills half the image (r^4 < 0.01): loose tolerance.
    error = np.abs(result.camera.distortion[:4] - TYPICAL_DISTORTION)
    assert np.all(error < [0.02, 0.1, 0.002, 0.002])
    held_out = panel_rig(columns=4, rows=3, depths=(0.05, 0.25), pitch=0.12)
    error = np.linalg.norm(result.camera.project(held_out) - truth.project(held_out), axis=1)
    assert np.max(error) < 0.5


def test_as_accurate_as_cv2_calibrate_camera(noisy_rig) -> None:
    truth, points, pixels = noisy_rig
    ours = calibrate(points, pixels, fix_skew=True)
    guess = np.array([[700.0, 0, 320], [0, 700.0, 240], [0, 0, 1]])
    flags = cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_K3
    rms_cv, K_cv, dist_cv, rvecs, tvecs = cv2.calibrateCamera(
        [points.astype(np.float32)],
        [pixels.astype(np.float32)],
        (640, 480),
        guess,
        None,
        flags=flags,
    )
    assert ours.rms_px <= rms_cv * 1.001
    held_out = panel_rig(columns=4, rows=3, depths=(0.05, 0.25), pitch=0.12)
    expected = truth.project(held_out)
    cv_proj, _ = cv2.projectPoints(held_out, rvecs[0], tvecs[0], K_cv, dist_cv)
    error_cv = np.sqrt(np.mean(np.sum((cv_proj.reshape(-1, 2) - expected) ** 2, axis=1)))
    error_ours = np.sqrt(np.mean(np.sum((ours.camera.project(held_out) - expected) ** 2, axis=1)))
    assert error_ours <= error_cv * 1.05


def test_linear_only_and_no_distortion(noisy_rig) -> None:
    truth, points, _ = noisy_rig
    pinhole = PinholeCamera(truth.intrinsics, truth.R, truth.d)
    pixels = pinhole.project(points)
    linear = calibrate(points, pixels, refine=False)
    assert linear.rms_px < 1e-8
    refined = calibrate(points, pixels, distortion_terms=0)
    np.testing.assert_allclose(refined.camera.distortion, 0.0)
    assert linear_camera(points, pixels).intrinsics.fx == pytest.approx(820.0, rel=1e-9)


def test_refinement_needs_enough_points() -> None:
    truth = rig_camera()
    points = panel_rig()[[0, 5, 20, 40, 60, 90, 100]]
    with pytest.raises(DegenerateGeometryError, match="at least 8"):
        refine_camera(truth, points, truth.project(points))
    with pytest.raises(ValueError, match="distortion_terms"):
        refine_camera(truth, points, truth.project(points), distortion_terms=3)
