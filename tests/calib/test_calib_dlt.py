"""DLT (Appendix A) and decomposition (Appendix B) on synthetic data with known truth."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.calib.decompose import (
    compose_camera_matrix,
    decompose_camera_matrix,
    normalize_camera_matrix,
)
from umbra.modules.calib.dlt import dlt_camera_matrix, project, reprojection_errors
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.rotations import rotation_from_vector
from umbra.modules.calib.synthetic import panel_rig, rig_camera

TRUTH = Intrinsics(fx=820.0, fy=815.0, skew=-3.5, u0=331.0, v0=244.0)


def true_camera_matrix() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    R = rotation_from_vector([0.08, -0.12, 0.03])
    d = np.array([0.01, -0.02, 1.1])
    return compose_camera_matrix(TRUTH, R, d), R, d


def test_dlt_recovers_exact_camera() -> None:
    P, _, _ = true_camera_matrix()
    X = panel_rig()
    estimate = dlt_camera_matrix(X, project(P, X))
    np.testing.assert_allclose(estimate, normalize_camera_matrix(P), rtol=1e-9, atol=1e-9)


def test_dlt_with_noise_has_small_error_and_decomposes_near_truth() -> None:
    rng = np.random.default_rng(3)
    P, R, d = true_camera_matrix()
    X = panel_rig()
    uv = project(P, X) + rng.normal(0, 0.3, (len(X), 2))
    estimate = dlt_camera_matrix(X, uv)
    errors = reprojection_errors(estimate, X, uv)
    assert np.sqrt(np.mean(errors**2)) < 0.5
    intrinsics, R_est, d_est = decompose_camera_matrix(estimate)
    assert intrinsics.fx == pytest.approx(TRUTH.fx, rel=0.02)
    assert intrinsics.fy == pytest.approx(TRUTH.fy, rel=0.02)
    assert abs(intrinsics.u0 - TRUTH.u0) < 10 and abs(intrinsics.v0 - TRUTH.v0) < 10
    angle = np.linalg.norm(cv2.Rodrigues(R_est.T @ R)[0])
    assert angle < np.radians(1.0)
    assert np.linalg.norm(d_est - d) < 0.02


def test_dlt_normalization_survives_far_away_coordinates() -> None:
    # A workcell frame 1 km from the rig: without Hartley normalization the design matrix has a
    # condition number ~1e12 and loses most digits.
    _, R, d = true_camera_matrix()
    offset = np.array([1000.0, -500.0, 200.0])
    X = panel_rig() + offset
    P_far = compose_camera_matrix(TRUTH, R, d - R @ offset)
    estimate = dlt_camera_matrix(X, project(P_far, X))
    assert np.max(reprojection_errors(estimate, X, project(P_far, X))) < 1e-6


def test_coplanar_points_are_refused() -> None:
    P, _, _ = true_camera_matrix()
    X = panel_rig(depths=(0.1,))
    with pytest.raises(DegenerateGeometryError, match="coplanar"):
        dlt_camera_matrix(X, project(P, X))
    # Tilted plane, not aligned with an axis.
    X_tilted = X @ rotation_from_vector([0.4, 0.3, 0.0]).T
    with pytest.raises(DegenerateGeometryError, match="coplanar"):
        dlt_camera_matrix(X_tilted, project(P, X_tilted))


def test_collinear_and_too_few_points_are_refused() -> None:
    P, _, _ = true_camera_matrix()
    line = np.outer(np.linspace(0, 1, 10), [0.1, 0.2, 0.3])
    with pytest.raises(DegenerateGeometryError, match="collinear"):
        dlt_camera_matrix(line, project(P, line))
    X = panel_rig()[[0, 10, 40, 50, 80]]
    with pytest.raises(DegenerateGeometryError, match="at least 6"):
        dlt_camera_matrix(X, project(P, X))


def test_rank_deficient_design_is_refused() -> None:
    # Six pairs of which two are the same point: 12 equations but only 10 independent ones.
    P, _, _ = true_camera_matrix()
    X = np.array(
        [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1], [0.1, 0.1, 0.1], [0.1, 0.1, 0.1]],
        dtype=float,
    )
    with pytest.raises(DegenerateGeometryError, match="rank"):
        dlt_camera_matrix(X, project(P, X))


def test_mirrored_data_is_refused() -> None:
    P, _, _ = true_camera_matrix()
    X = panel_rig()
    mirrored = X * [1, 1, -1]  # left-handed point coordinates
    with pytest.raises(DegenerateGeometryError, match="behind"):
        dlt_camera_matrix(mirrored, project(P, X))


def test_bad_shapes_and_values() -> None:
    with pytest.raises(DegenerateGeometryError, match=r"\(n, 3\)"):
        dlt_camera_matrix(np.zeros((8, 2)), np.zeros((8, 2)))
    with pytest.raises(DegenerateGeometryError, match="finite"):
        X = panel_rig()
        uv = np.zeros((len(X), 2))
        uv[3, 0] = np.nan
        dlt_camera_matrix(X, uv)


def test_decomposition_of_known_camera_is_exact() -> None:
    P, R, d = true_camera_matrix()
    for scale in (1.0, -2.5, 1e-4):
        intrinsics, R_est, d_est = decompose_camera_matrix(scale * P)
        np.testing.assert_allclose(intrinsics.as_array(), TRUTH.as_array(), rtol=1e-12)
        np.testing.assert_allclose(R_est, R, atol=1e-13)
        np.testing.assert_allclose(d_est, d, atol=1e-13)
        assert np.linalg.det(R_est) == pytest.approx(1.0, abs=1e-12)


def test_decomposition_agrees_with_opencv() -> None:
    P, _, _ = true_camera_matrix()
    K_cv, R_cv, c_cv, *_ = cv2.decomposeProjectionMatrix(P)
    intrinsics, R, d = decompose_camera_matrix(P)
    np.testing.assert_allclose(intrinsics.matrix(), K_cv / K_cv[2, 2], rtol=1e-9)
    np.testing.assert_allclose(R, R_cv, atol=1e-12)
    np.testing.assert_allclose(-R.T @ d, (c_cv[:3] / c_cv[3]).ravel(), atol=1e-12)


def test_points_in_front_have_positive_depth() -> None:
    camera = rig_camera(distortion=np.zeros(4))
    P = camera.camera_matrix()
    X = panel_rig()
    _, R, d = decompose_camera_matrix(-7.0 * P)
    assert np.all(X @ R[2] + d[2] > 0)


@settings(max_examples=60, deadline=None)
@given(
    fx=st.floats(50, 30000),
    aspect=st.floats(0.5, 2.0),
    skew=st.floats(-50, 50),
    u0=st.floats(-200, 1000),
    v0=st.floats(-200, 1000),
    rvec=st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
    d=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
    scale=st.floats(1e-3, 1e3) | st.floats(-1e3, -1e-3),
)
def test_round_trip_compose_decompose_compose(fx, aspect, skew, u0, v0, rvec, d, scale) -> None:
    intrinsics = Intrinsics(fx, fx * aspect, skew, u0, v0)
    R = rotation_from_vector(rvec)
    P = compose_camera_matrix(intrinsics, R, d)
    again = compose_camera_matrix(*decompose_camera_matrix(scale * P))
    assert np.linalg.norm(again - P) <= 1e-9 * np.linalg.norm(P)
    recovered, R_est, _ = decompose_camera_matrix(scale * P)
    assert recovered.fx > 0 and recovered.fy > 0
    assert np.linalg.det(R_est) == pytest.approx(1.0, abs=1e-9)


def test_singular_matrix_is_refused() -> None:
    with pytest.raises(DegenerateGeometryError, match="singular"):
        decompose_camera_matrix(np.zeros((3, 4)))
