"""Issue #31 item 4: every uncertainty a sketch reports is what Monte Carlo finds.

True cameras and a true triad (three orthogonal edges from one vertex) are built here; clicks are
the true vertices projected with ``cv2.projectPoints`` (distortion included) plus Gaussian noise;
the cameras the sketch is given are the true ones with calibration errors drawn (independently
of the project's code) with the sigmas of :class:`StereoNoise`. Over many draws the normalized
estimation error squared (NEES) of each reported covariance must fall in its 95 % chi-square band:
the vertices (after the epipolar step), the triad box's centre, a line's direction.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from umbra.modules.ptu.aim import look_at
from umbra.modules.sketch.primitives import (
    line_direction_covariance,
    place_primitive,
    triad_box,
    vertex_covariance,
)
from umbra.modules.sketch.stereo import StereoNoise, StereoPair

#: clicks on the true corners (features: no handle error along an edge, test_sketch_depth_trust)
NOISE = StereoNoise(
    pixel_px=0.5, rotation_rad=3e-4, translation_m=3e-4, focal_rel=2e-3, handle_px=0.0
)
K = np.array([[1500.0, 0.0, 330.0], [0.0, 1490.0, 235.0], [0.0, 0.0, 1.0]])
DIST = np.array([-0.2, 0.05, 0.0005, -0.0003, 0.0])
RUNS = 60


TARGET = np.array([1.6, 0.05, 0.3])
CAMERAS = (look_at(np.array([0.0, 0.3, 1.0]), TARGET), look_at(np.array([0.0, -0.3, 1.0]), TARGET))
#: the true triad: vertex 0 and three orthogonal edges of 10, 7 and 5 cm
EDGES = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix() * np.array([0.10, 0.07, 0.05])
VERTICES = np.vstack([TARGET, TARGET + EDGES.T])
TRUE_CENTRE = TARGET + 0.5 * EDGES.sum(axis=1)


def project(T_base_camera: np.ndarray, points: np.ndarray) -> np.ndarray:
    T = np.linalg.inv(T_base_camera)
    rvec = cv2.Rodrigues(T[:3, :3])[0]
    return cv2.projectPoints(points, rvec, T[:3, 3], K, DIST)[0].reshape(-1, 2)


def estimated_camera(rng, T_true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A calibration with errors: rotation and position in the camera's own frame, focal length
    (both axes together), principal point."""
    T = T_true.copy()
    T[:3, :3] = (
        T_true[:3, :3] @ Rotation.from_rotvec(rng.normal(0, NOISE.rotation_rad, 3)).as_matrix()
    )
    T[:3, 3] = T_true[:3, 3] + T_true[:3, :3] @ rng.normal(0, NOISE.translation_m, 3)
    K_est = K.copy()
    K_est[:2, :2] *= 1.0 + rng.normal(0, NOISE.focal_rel)
    K_est[:2, 2] += rng.normal(0, NOISE.principal_px, 2)
    return K_est, T


def band(runs: int, dof: int) -> tuple[float, float]:
    low, high = chi2.ppf([0.025, 0.975], runs * dof)
    return low / runs, high / runs


@pytest.mark.slow
@pytest.mark.untimed
@pytest.mark.timeout(900)
def test_vertices_box_centre_and_line_direction_nees() -> None:
    rng = np.random.default_rng(2026)
    clicks_a, clicks_b = project(CAMERAS[0], VERTICES), project(CAMERAS[1], VERTICES)
    true_direction = EDGES[:, 0] / np.linalg.norm(EDGES[:, 0])
    vertex_nees, corner_nees, centre_nees, direction_nees = [], [], [], []
    for _ in range(RUNS):
        (Ka, Ta), (Kb, Tb) = estimated_camera(rng, CAMERAS[0]), estimated_camera(rng, CAMERAS[1])
        pair = StereoPair(Ka, Ta, Kb, Tb, DIST, DIST)
        a = clicks_a + rng.normal(0, NOISE.pixel_px, clicks_a.shape)
        b = clicks_b + rng.normal(0, NOISE.pixel_px, clicks_b.shape)
        triad = place_primitive(pair, "triad", a, b, NOISE, primitive_id="t")
        # all four vertices at once: they share the calibration's errors
        e = (triad.points - VERTICES).ravel()
        vertex_nees.append(e @ np.linalg.solve(vertex_covariance(triad, pair, NOISE), e))
        e = triad.points[0] - VERTICES[0]
        corner_nees.append(e @ np.linalg.solve(triad.covariances[0], e))
        box = triad_box(triad, pair=pair, noise=NOISE)
        e = box.T_base_box[:3, 3] - TRUE_CENTRE
        centre_nees.append(e @ np.linalg.solve(box.covariance, e))
        line = place_primitive(pair, "line", a[:2], b[:2], NOISE, primitive_id="l")
        direction, covariance = line_direction_covariance(line, pair, NOISE)
        e = direction - true_direction
        direction_nees.append(e @ np.linalg.pinv(covariance, rcond=1e-9) @ e)
    for name, values, dof in (
        ("vertices", vertex_nees, 12),
        ("vertex 0", corner_nees, 3),
        ("box centre", centre_nees, 3),
        ("line direction", direction_nees, 2),
    ):
        low, high = band(len(values), dof)
        assert low < np.mean(values) < high, (name, np.mean(values), (low, high))
