"""Issue #31 item 3: vsServo undistorts contours with the whole camera model, skew included.

The reference is independent of the project's code: the Brown-Conrady forward model written out
here, inverted point by point with ``scipy.optimize.root``. ``cv2.undistortPoints`` drops the
camera matrix's skew (1.8-2.4 px off with the report's -4.58 px).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import root

from tests.servo.servo_scene import SCENE_PARAMS, camera_above, patch_corners
from umbra.connectors.messages import CameraModel, Contour
from umbra.modules.servo.vsservo import VsServo
from umbra.runtime.harness import ModuleHarness

#: the report's zoom camera at zoom 0 (skew -4.58 px) with a strong lens
FX, FY, SKEW, U0, V0 = 740.09, 741.60, -4.58, 344.25, 212.84
DIST = np.array([-0.28, 0.11, 0.0012, -0.0009, -0.02])
PARAMS = {**SCENE_PARAMS, "standoff": 0.2, "acquire_frames": 1, "settle_frames": 3}


def forward(xy: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Ideal normalized coordinates to distorted pixels (OpenCV's model, then K with skew)."""
    k1, k2, p1, p2, k3 = dist
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([FX * xd + SKEW * yd + U0, FY * yd + V0], axis=-1)


def reference_normalized(pixels: np.ndarray) -> np.ndarray:
    out = []
    for uv in pixels:
        guess = np.array([(uv[0] - U0) / FX, (uv[1] - V0) / FY])
        solution = root(lambda xy, uv=uv: forward(xy, DIST) - uv, guess, tol=1e-13)
        assert np.max(np.abs(forward(solution.x, DIST) - uv)) < 1e-8
        out.append(solution.x)
    return np.array(out)


def model(dist: np.ndarray) -> CameraModel:
    return CameraModel(fx=FX, fy=FY, skew=SKEW, u0=U0, v0=V0, dist=dist)


def contour(pixels: np.ndarray) -> Contour:
    return Contour(
        vertices=pixels,
        centroid=pixels.mean(axis=0),
        area=0.0,
        orientation=0.0,
        axes=np.zeros(2),
        status="tracking",
    )


def patch_normalized() -> np.ndarray:
    T_camera_world = np.linalg.inv(camera_above(0.06, 0.05, 0.3, 10.0))
    p = patch_corners() @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
    return p[:, :2] / p[:, 2:3]


def test_undistorted_contour_matches_scipy_root_of_the_skewed_model() -> None:
    rng = np.random.default_rng(3)
    pixels = np.column_stack([rng.uniform(0, 640, 40), rng.uniform(0, 480, 40)])
    expected = reference_normalized(pixels)
    with ModuleHarness(VsServo, PARAMS) as h:
        h.push("camera", model(DIST))
        h.step(0.02)
        got = h.module._normalized(pixels)
    # in pixels at the focal length: well under a thousandth of a pixel
    assert np.max(np.abs(got - expected)) * FX < 1e-3


def test_servo_error_with_a_skewed_distorted_camera_equals_the_ideal_camera() -> None:
    ideal_xy = patch_normalized()
    statuses = []
    for dist in (DIST, np.zeros(5)):
        with ModuleHarness(VsServo, PARAMS) as h:
            h.push("camera", model(dist))
            for _ in range(2):
                h.push("contour", contour(forward(ideal_xy, dist)))
                h.step(0.02)
            statuses.append(h.output("status").values)
    for name in ("error_x", "error_y", "error_z", "error_roll"):
        assert statuses[0][name] == pytest.approx(statuses[1][name], abs=1e-6)
