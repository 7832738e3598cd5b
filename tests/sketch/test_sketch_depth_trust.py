"""Issue #41 item 3: a primitive's stated uncertainty includes the operator's handle error along
the ambiguous direction, and a poorly constrained depth is flagged with what to do.

The issue's case is the shipped rig on the nominal scene: cameras 0.5 m apart along y, the pipe
along y, so in image b the epipolar lines run along the pipe and where a handle sits along it
sets the depth (both image-b handles 10 px along the pipe move the line ~22 mm).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import chi2

from umbra.modules.sketch.depth_check import WARN_ANGLE_DEG, depth_warnings, vertex_depths
from umbra.modules.sketch.primitives import place_primitive, vertex_covariance
from umbra.modules.sketch.session import SketchSession
from umbra.modules.sketch.stereo import StereoNoise, StereoPair
from umbra.modules.world.scene_objects import SketchScene


def _cell(
    scene: SketchScene, at: np.ndarray, zoom: float = 0.3
) -> tuple[SketchSession, StereoPair]:
    session = SketchSession(scene, seed=0)
    session.aim(at, zoom=zoom)
    session.snapshot(render=False)
    return session, StereoPair.from_snapshot(session.snapshots["snap1"])


def _sigma_mm(prim) -> np.ndarray:
    return np.sqrt(np.linalg.eigvalsh(prim.covariances)[:, -1]) * 1e3


def test_the_issues_pipe_states_its_handle_error_and_warns() -> None:
    scene = SketchScene.nominal()
    session, pair = _cell(scene, scene.pipe.center)
    points = scene.pipe.top_ends
    a, b = session.true_pixels(points)
    line = session.place("line", a, b)
    along = (b[1] - b[0]) / np.linalg.norm(b[1] - b[0])  # the pipe's direction in image b
    moved = session.place("line", a, b + 10.0 * along)
    shift_mm = np.linalg.norm(moved.points - line.points, axis=1) * 1e3
    assert np.all((shift_mm > 18.0) & (shift_mm < 26.0)), shift_mm  # the issue's ~22 mm
    # the stated sigma covers that 10 px slip (the declared handle error is 20 px)
    sigma = _sigma_mm(line)
    assert np.all(sigma > shift_mm), (sigma, shift_mm)
    assert np.all(sigma > 35.0) and np.all(sigma < 60.0), sigma
    # click noise alone said ~4 mm: the issue's complaint
    click_only = place_primitive(pair, "line", a, b, StereoNoise(handle_px=0.0), primitive_id="c")
    assert np.all(_sigma_mm(click_only) < 7.0), _sigma_mm(click_only)
    depths = vertex_depths(pair, line)
    assert all(d.flagged and d.angle_deg < 1.0 for d in depths), depths
    (warning,) = depth_warnings(pair, line)
    assert warning.startswith("line1: depth poorly constrained")
    assert "2.2 mm per px" in warning and f"stated sigma {max(sigma):.0f} mm" in warning
    for remedy in ("features that cross the epipolar lines", "live wrist view"):
        assert remedy in warning


def test_a_line_across_the_epipolar_lines_has_no_warning_and_the_click_sigma() -> None:
    scene = SketchScene.nominal()
    door = scene.door
    hinge = np.stack([door.hinge_top, door.hinge])  # vertical: across the horizontal lines
    session, pair = _cell(scene, door.hinge + np.array([0.0, 0.0, 0.2]), zoom=0.1)
    a, b = session.true_pixels(hinge)
    line = session.place("line", a, b)
    assert depth_warnings(pair, line) == []
    assert all(d.angle_deg > 60.0 and not d.flagged for d in vertex_depths(pair, line))
    click_only = place_primitive(pair, "line", a, b, StereoNoise(handle_px=0.0), primitive_id="c")
    # near the click noise's (the handle now follows the edge: a slip along it is no error)
    assert np.allclose(_sigma_mm(line), _sigma_mm(click_only), rtol=0.1)
    # a point sits on a feature: the click noise, no warning
    point = session.place("point", a[:1], b[:1])
    assert depth_warnings(pair, point) == []


def test_a_triad_flags_only_the_vertex_whose_edge_runs_along_the_lines() -> None:
    scene = SketchScene.nominal()
    centre = scene.pipe.center
    # corner, then edges along y (the baseline: along the epipolar lines), x and z
    corner = centre + np.array([0.0, -0.05, 0.1])
    vertices = corner + np.array([[0, 0, 0], [0, 0.1, 0], [0.1, 0, 0], [0, 0, 0.1]])
    session, pair = _cell(scene, centre)
    triad = session.place("triad", *session.true_pixels(vertices))
    flags = [d.flagged for d in vertex_depths(pair, triad)]
    assert flags == [False, True, False, False], vertex_depths(pair, triad)
    (warning,) = depth_warnings(pair, triad)
    assert warning.startswith("triad1 vertex 1: depth poorly constrained")
    sigma = _sigma_mm(triad)
    assert sigma[1] > 5 * max(sigma[0], sigma[2], sigma[3]), sigma


def _person_drags_b(snap, point: np.ndarray, a: np.ndarray, edge_b: np.ndarray, rng, noise):
    """Where the simulated person leaves image b's handle, computed here from OpenCV alone: they
    believe the point is at its true image plus ``pixel_px`` across the edge and ``handle_px``
    along it, and drag the handle along the epipolar line of their image-a click to the spot
    most consistent with that belief (Mahalanobis-nearest)."""
    Ta, Tb = np.linalg.inv(snap.T_base_camera_a), np.linalg.inv(snap.T_base_camera_b)
    ray = cv2.undistortPoints(a.reshape(1, 1, 2), snap.K_a, snap.dist_a).reshape(2)
    depth = np.linalg.norm(Ta[:3, :3] @ point + Ta[:3, 3])
    cam = np.append(ray, 1.0) / np.linalg.norm(np.append(ray, 1.0))
    on_ray = [Ta[:3, :3].T @ (cam * (depth + d) - Ta[:3, 3]) for d in (-0.01, 0.01)]
    rvec = cv2.Rodrigues(Tb[:3, :3])[0]
    ends = cv2.projectPoints(np.array(on_ray), rvec, Tb[:3, 3], snap.K_b, snap.dist_b)[0]
    p0, p1 = ends.reshape(2, 2)
    e = (p1 - p0) / np.linalg.norm(p1 - p0)
    truth = cv2.projectPoints(point.reshape(1, 3), rvec, Tb[:3, 3], snap.K_b, snap.dist_b)[0]
    t = edge_b / np.linalg.norm(edge_b)
    n = np.array([-t[1], t[0]])
    slip = n * rng.normal(0, noise.pixel_px) + t * rng.normal(0, noise.handle_px)
    belief = truth.reshape(2) + slip
    W = np.outer(n, n) / noise.pixel_px**2 + np.outer(t, t) / noise.handle_px**2
    s = e @ W @ (belief - p0) / (e @ W @ e)
    return p0 + s * e


@pytest.mark.parametrize(
    ("scene_seed", "angle_range"),
    [(None, (0.0, 1.0)), (0, (10.0, WARN_ANGLE_DEG)), (4, (WARN_ANGLE_DEG - 5.0, 30.0))],
)
def test_stated_covariance_covers_a_person_dragging_handles_monte_carlo(
    scene_seed: int | None, angle_range: tuple[float, float]
) -> None:
    """150 placements of a line on the pipe (fixed seed) by the person above, clicks 1 px, handle
    20 px; calibration exact (its errors: test_sketch_uncertainty_mc). The joint NEES of both
    vertices falls in its 99 % chi-square band and ~95 % of errors lie inside the stated 95 %
    ellipsoid."""
    scene = (
        SketchScene.nominal()
        if scene_seed is None
        else SketchScene.random(np.random.default_rng(scene_seed))
    )
    noise = StereoNoise(1.0, 0.0, 0.0, 0.0, 0.0, handle_px=20.0)
    session, pair = _cell(scene, scene.pipe.center)
    snap = session.snapshots["snap1"]
    ends = scene.pipe.top_ends
    points = ends[0] + np.outer([0.25, 0.75], ends[1] - ends[0])  # on the featureless stretch
    true_a, true_b = session.true_pixels(points)
    rng = np.random.default_rng(41)
    nees, angles = [], []
    for _ in range(150):
        a = true_a + rng.normal(0, noise.pixel_px, true_a.shape)
        edge = true_b[1] - true_b[0]
        b = np.stack([_person_drags_b(snap, points[i], a[i], edge, rng, noise) for i in (0, 1)])
        line = place_primitive(pair, "line", a, b, noise, primitive_id="l")
        e = (line.points - points).ravel()
        nees.append(e @ np.linalg.solve(vertex_covariance(line, pair, noise), e))
        angles += [d.angle_deg for d in vertex_depths(pair, line)]
    assert angle_range[0] <= np.median(angles) <= angle_range[1], np.median(angles)
    low, high = chi2.ppf([0.005, 0.995], len(nees) * 6) / len(nees)
    assert low < np.mean(nees) < high, (np.mean(nees), (low, high))
    inside = np.mean(np.asarray(nees) <= chi2.ppf(0.95, 6))
    assert 0.90 <= inside <= 0.99, inside


def test_the_page_state_carries_the_warnings_next_to_the_primitive() -> None:
    from umbra.modules.sketch_page.page_state import page_state

    scene = SketchScene.nominal()
    session, pair = _cell(scene, scene.pipe.center)
    pipe = session.place("line", *session.true_pixels(scene.pipe.top_ends))
    door = scene.door
    hinge = session.place("line", *session.true_pixels(np.stack([door.hinge_top, door.hinge])))
    state = page_state(session.snapshots["snap1"], [pipe, hinge], None, None, None)
    shown = {entry["id"]: entry["warnings"] for entry in state["primitives"]}
    assert shown == {"line1": depth_warnings(pair, pipe), "line2": []}
    assert shown["line1"][0].startswith("line1: depth poorly constrained")
