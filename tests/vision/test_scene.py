"""The simulated wrist camera: geometry against OpenCV, lighting, noise, blur, occlusion."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from umbra.modules.geometry.transforms import transform_points
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.lighting import Lighting, apply_lighting, motion_blur_kernel
from umbra.modules.vision.metrics import polygon_iou, polygon_mask
from umbra.modules.vision.polygon import signed_area
from umbra.modules.vision.scene import (
    LABEL_DISTRACTOR,
    LABEL_OCCLUDER,
    LABEL_PATCH,
    Occluder,
    Scene,
    SceneRenderer,
    distractor_touching,
    patch_outline,
    pose,
)

from .conftest import DISTORTION, INTRINSICS, T_WORLD_CAMERA

PATCH_POSE = pose((0.006, -0.004, 0.03), 0.4)


def opencv_projection(T_world_camera: np.ndarray, points_world: np.ndarray) -> np.ndarray:
    T_camera_world = np.linalg.inv(T_world_camera)
    rvec, _ = cv2.Rodrigues(T_camera_world[:3, :3])
    pixels, _ = cv2.projectPoints(
        points_world, rvec, T_camera_world[:3, 3], INTRINSICS.matrix(), DISTORTION
    )
    return pixels.reshape(-1, 2)


@pytest.mark.parametrize("tilt_deg", [0.0, 12.0, -20.0])
def test_ground_truth_polygon_matches_project_points(renderer, rng, tilt_deg: float) -> None:
    tilt = np.deg2rad(tilt_deg)
    T_world_camera = T_WORLD_CAMERA.copy()
    c, s = np.cos(tilt), np.sin(tilt)
    T_world_camera[:3, :3] = T_WORLD_CAMERA[:3, :3] @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    frame = renderer.render(Scene(T_world_patch=PATCH_POSE), T_world_camera, rng=rng)
    corners_world = transform_points(PATCH_POSE, patch_outline((0.06, 0.04), 1))
    expected = opencv_projection(T_world_camera, corners_world)
    np.testing.assert_allclose(frame.patch_corners, expected, atol=1e-6)
    per_edge = len(frame.patch_polygon) // 4
    np.testing.assert_allclose(frame.patch_polygon[::per_edge], expected, atol=1e-6)
    outline_world = transform_points(PATCH_POSE, patch_outline((0.06, 0.04), per_edge))
    np.testing.assert_allclose(
        frame.patch_polygon, opencv_projection(T_world_camera, outline_world), atol=1e-6
    )


def test_rendered_patch_covers_the_ground_truth_polygon(renderer, rng) -> None:
    frame = renderer.render(Scene(T_world_patch=PATCH_POSE), T_WORLD_CAMERA, rng=rng)
    drawn = frame.labels == LABEL_PATCH
    truth = polygon_mask(frame.patch_polygon, drawn.shape)
    iou = np.count_nonzero(drawn & truth) / np.count_nonzero(drawn | truth)
    assert iou > 0.98
    assert frame.patch_visible_fraction == pytest.approx(1.0, abs=0.02)
    # The pixels inside the outline have the patch's color (RGB (30, 170, 60) -> BGR).
    inner = cv2.erode(truth.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    np.testing.assert_allclose(frame.image[inner].mean(axis=0), [60, 170, 30], atol=1.0)


def test_rendering_is_deterministic_for_a_seed(renderer) -> None:
    lighting = Lighting(noise_sigma=8.0)
    scene = Scene(T_world_patch=PATCH_POSE, background="photo")
    first = renderer.render(scene, T_WORLD_CAMERA, lighting, np.random.default_rng(3))
    again = renderer.render(scene, T_WORLD_CAMERA, lighting, np.random.default_rng(3))
    other = renderer.render(scene, T_WORLD_CAMERA, lighting, np.random.default_rng(4))
    np.testing.assert_array_equal(first.image, again.image)
    assert np.count_nonzero(first.image != other.image) > first.image.size // 2


def test_gain_and_cast_scale_the_channels(renderer, rng) -> None:
    scene = Scene(T_world_patch=PATCH_POSE)
    plain = renderer.render(scene, T_WORLD_CAMERA, rng=rng).image.astype(float)
    lit = renderer.render(
        scene, T_WORLD_CAMERA, Lighting(gain=0.5, cast_rgb=(1.2, 1.0, 0.8)), rng=rng
    ).image.astype(float)
    expected = np.clip(np.rint(plain * 0.5 * np.array([0.8, 1.0, 1.2])), 0, 255)
    assert np.abs(lit - expected).max() <= 1.0


def test_noise_has_the_requested_sigma_and_no_bias() -> None:
    flat = np.full((240, 320, 3), 120, dtype=np.uint8)
    noisy = apply_lighting(flat, Lighting(noise_sigma=8.0), np.random.default_rng(9))
    deviation = noisy.astype(float) - 120.0
    assert deviation.std() == pytest.approx(8.0, rel=0.03)
    assert abs(deviation.mean()) < 0.1
    # Independent from pixel to pixel: neighbours are uncorrelated.
    correlation = np.corrcoef(deviation[:, :-1, 0].ravel(), deviation[:, 1:, 0].ravel())[0, 1]
    assert abs(correlation) < 0.02


def test_motion_blur_smears_edges_along_its_direction() -> None:
    image = np.zeros((60, 60, 3), dtype=np.uint8)
    image[:, 30:] = 200  # a vertical edge
    kernel = motion_blur_kernel(9.0, 0.0)
    assert kernel.sum() == pytest.approx(1.0, abs=1e-6)
    along = apply_lighting(image, Lighting(blur_length_px=9.0), np.random.default_rng(0))
    across = apply_lighting(
        image, Lighting(blur_length_px=9.0, blur_angle_rad=np.pi / 2), np.random.default_rng(0)
    )
    ramp = np.count_nonzero((along[30, :, 0] > 5) & (along[30, :, 0] < 195))
    assert 7 <= ramp <= 10
    np.testing.assert_array_equal(across[30], image[30])


def test_photo_background_is_the_bundled_coffee_image(renderer, rng) -> None:
    from skimage import data

    coffee = data.coffee()  # RGB, bundled with scikit-image: no download
    scene = Scene(
        T_world_patch=PATCH_POSE,
        background="photo",
        photo_center_m=(0.0, 0.0),
        photo_size_m=(0.6, 0.4),
        tray_size_m=(0.01, 0.01),
        tool_size_m=(0.01, 0.01),
        patch_present=False,
    )
    frame = renderer.render(scene, T_WORLD_CAMERA, rng=rng)
    rows, cols = coffee.shape[:2]
    grid = np.array([(u, v) for u in (210, 260, 340, 390) for v in (140, 180, 230, 260)], float)
    errors = []
    for col, row in grid:
        # Texture pixel -> table point (metres) as laid out by the scene, then -> image.
        x = -0.3 + (col / cols) * 0.6
        y = 0.2 - (row / rows) * 0.4
        u, v = opencv_projection(T_WORLD_CAMERA, np.array([[x, y, 0.0]]))[0]
        seen = frame.image[round(v) - 1 : round(v) + 2, round(u) - 1 : round(u) + 2]
        errors.append(np.abs(seen.mean(axis=(0, 1))[::-1] - coffee[int(row), int(col)]).max())
    assert np.median(errors) < 20


def test_visibility_under_occlusion_and_removal(renderer, rng) -> None:
    half = np.array([[0.0, -0.05, 0.01], [0.1, -0.05, 0.01], [0.1, 0.05, 0.01], [0.0, 0.05, 0.01]])
    occluder = Occluder(transform_points(PATCH_POSE, half), rgb=(220, 180, 150))
    frame = renderer.render(
        Scene(T_world_patch=PATCH_POSE, occluders=(occluder,)), T_WORLD_CAMERA, rng=rng
    )
    assert frame.patch_visible_fraction == pytest.approx(0.5, abs=0.03)
    assert np.count_nonzero(frame.labels == LABEL_OCCLUDER) > 0
    gone = renderer.render(
        Scene(T_world_patch=PATCH_POSE, patch_present=False), T_WORLD_CAMERA, rng=rng
    )
    assert gone.patch_visible_fraction == 0.0
    assert gone.patch_polygon.shape == (0, 2)
    assert np.count_nonzero(gone.labels == LABEL_PATCH) == 0


def test_image_frame_occluder_is_drawn_where_given(renderer, rng) -> None:
    square = np.array([[10.0, 10.0], [110.0, 10.0], [110.0, 60.0], [10.0, 60.0]])
    occluder = Occluder(square, frame="image", rgb=(0, 0, 255))
    frame = renderer.render(Scene(occluders=(occluder,)), T_WORLD_CAMERA, rng=rng)
    np.testing.assert_array_equal(frame.image[30, 50], [255, 0, 0])
    assert polygon_iou(square, square, (480, 640)) == 1.0
    drawn = frame.labels == LABEL_OCCLUDER
    assert np.count_nonzero(drawn) == pytest.approx(100 * 50, rel=0.05)


@pytest.mark.parametrize("side", ["+x", "-x", "+y", "-y"])
def test_distractor_touches_the_patch(renderer, rng, side: str) -> None:
    T_distractor = distractor_touching(PATCH_POSE, side=side, slide_m=0.01, yaw_rad=0.2)
    frame = renderer.render(
        Scene(T_world_patch=PATCH_POSE, distractors=(T_distractor,)), T_WORLD_CAMERA, rng=rng
    )
    patch = (frame.labels == LABEL_PATCH).astype(np.uint8)
    distractor = frame.labels == LABEL_DISTRACTOR
    touching = cv2.dilate(patch, np.ones((3, 3), np.uint8)).astype(bool) & distractor
    assert np.count_nonzero(touching) > 10
    # Same size and same color as the patch.
    assert np.count_nonzero(distractor) > 0.8 * np.count_nonzero(patch)
    np.testing.assert_allclose(
        frame.image[distractor].mean(axis=0), frame.image[patch.astype(bool)].mean(axis=0), atol=3
    )


def test_sky_beyond_the_horizon(rng) -> None:
    renderer = SceneRenderer(INTRINSICS)
    T_world_camera = np.eye(4)
    # Optical axis along world +x, image down = world -z: the horizon is the middle row.
    T_world_camera[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, -1], [1, 0, 0]])
    T_world_camera[:3, 3] = [-1.0, 0.0, 0.3]
    frame = renderer.render(Scene(sky_rgb=(10, 20, 250)), T_world_camera, rng=rng)
    np.testing.assert_array_equal(frame.image[100, 320], [250, 20, 10])
    assert not np.array_equal(frame.image[400, 320], [250, 20, 10])


@pytest.mark.parametrize("yaw_deg", [0.0, 10.0, 17.0, 45.0, 57.0, -17.0])
def test_patch_pixels_cover_exactly_the_ground_truth(renderer, yaw_deg: float) -> None:
    """The patch's pixel coverage has the ground-truth polygon's area and centroid (OpenCV's own
    anti-aliased fill is off by half a pixel at some angles; the renderer must not be)."""
    black = (0, 0, 0)
    scene = Scene(
        T_world_patch=pose((0.002, -0.001, 0.03), np.deg2rad(yaw_deg)),
        patch_rgb=(255, 255, 255),
        tool_rgb=black,
        tray_rgb=black,
        table_rgb=black,
    )
    frame = renderer.render(scene, T_WORLD_CAMERA)
    weight = frame.image[:, :, 1].astype(float) / 255.0
    rows, cols = np.mgrid[: weight.shape[0], : weight.shape[1]]
    truth = polygon_features(frame.patch_polygon)
    assert weight.sum() == pytest.approx(truth.area_px2, rel=0.005)
    centroid = ((weight * cols).sum() / weight.sum(), (weight * rows).sum() / weight.sum())
    np.testing.assert_allclose(centroid, truth.centroid_uv, atol=0.1)


def test_patch_fill_has_the_truth_polygon_area(renderer) -> None:
    """The rendered patch, unmixed from a uniform background, covers the truth polygon's area to
    0.05 % at any pose (the fill is the polygon's exact pixel coverage)."""
    background = (120, 100, 80)
    patch_bgr = np.array([60.0, 170.0, 30.0])
    table_bgr = np.array(background[::-1], dtype=float)
    for k in range(3):
        scene = Scene(
            T_world_patch=pose((0.004 * k - 0.006, 0.003, 0.03), 0.4 * k + 0.2),
            tool_rgb=background,
            tray_rgb=background,
            table_rgb=background,
        )
        frame = renderer.render(scene, T_WORLD_CAMERA)
        d = patch_bgr - table_bgr
        mix = (frame.image.astype(float) - table_bgr) @ d / (d @ d)
        area = abs(signed_area(frame.patch_polygon))
        assert mix.sum() == pytest.approx(area, rel=5e-4)
