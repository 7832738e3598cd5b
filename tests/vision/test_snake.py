"""The statistical pressure snake on simulated frames, scored by IoU against the ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.modules.vision import color
from umbra.modules.vision import snake as sn
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.metrics import polygon_iou
from umbra.modules.vision.polygon import rectangle, segment_lengths
from umbra.modules.vision.scene import Scene, pose
from umbra.modules.vision.snake_config import SnakeSettings

from .conftest import METRES_PER_PIXEL, T_WORLD_CAMERA

PARAMS = sn.SnakeParams()


def acquire_on(frame, seed_uv, params: sn.SnakeParams = PARAMS) -> sn.SnakeResult:
    model = color.fit(sn.seed_samples(frame.image, seed_uv, params.seed_radius_px))
    return sn.acquire(frame.image, seed_uv, model, params)


@pytest.mark.parametrize("gain", [0.5, 0.8, 1.0, 1.25, 1.5])
@pytest.mark.parametrize(
    "cast_rgb", [(1.0, 1.0, 1.0), (1.25, 1.0, 0.8), (0.8, 0.95, 1.3)], ids=["white", "warm", "cool"]
)
def test_grows_from_a_seed_point_onto_the_patch(renderer, gain, cast_rgb) -> None:
    rng = np.random.default_rng(round(gain * 100) + round(cast_rgb[0] * 10))
    T_world_patch = pose((*rng.uniform(-0.012, 0.012, 2), 0.03), rng.uniform(-np.pi, np.pi))
    lighting = Lighting(
        gain=gain,
        cast_rgb=cast_rgb,
        noise_sigma=8.0,
        blur_length_px=3.0,
        blur_angle_rad=rng.uniform(0, np.pi),
    )
    background = "photo" if gain >= 1.0 else "flat"
    frame = renderer.render(
        Scene(T_world_patch=T_world_patch, background=background), T_WORLD_CAMERA, lighting, rng
    )
    seed = frame.patch_polygon.mean(axis=0) + rng.uniform(-15, 15, 2)
    result = acquire_on(frame, seed)
    assert result.converged
    assert polygon_iou(result.vertices, frame.patch_polygon, (480, 640)) >= 0.95
    lengths = segment_lengths(result.vertices)
    assert lengths.min() >= PARAMS.min_segment_px - 1.0
    assert lengths.max() <= PARAMS.max_segment_px + 1.0


def test_collapses_from_a_region_onto_the_patch(renderer, rng) -> None:
    frame = renderer.render(
        Scene(T_world_patch=pose((0.004, 0.002, 0.03), 0.3)),
        T_WORLD_CAMERA,
        Lighting(noise_sigma=6.0),
        rng,
    )
    model = color.from_rgb((30, 170, 60), noise_gray=10.0)
    centre = frame.patch_polygon.mean(axis=0)
    region = rectangle(centre, (260.0, 200.0))
    result = sn.evolve(frame.image, sn.seed_region(region, PARAMS), model, PARAMS)
    assert result.converged
    assert polygon_iou(result.vertices, frame.patch_polygon, (480, 640)) >= 0.95


def test_follows_a_moving_turning_patch(renderer, rng) -> None:
    """10 px and 5 degrees per frame; a few iterations per frame from the last contour."""
    lighting = Lighting(noise_sigma=8.0, blur_length_px=2.0)
    step_m = 10.0 * METRES_PER_PIXEL

    def frame_at(k: int):
        T_world_patch = pose((-0.02 + k * step_m, 0.004 - 0.3 * k * step_m, 0.03), 0.1 * k)
        return renderer.render(Scene(T_world_patch=T_world_patch), T_WORLD_CAMERA, lighting, rng)

    first = frame_at(0)
    model = color.fit(sn.seed_samples(first.image, first.patch_polygon.mean(axis=0), 5.0))
    vertices = sn.acquire(first.image, first.patch_polygon.mean(axis=0), model, PARAMS).vertices
    scores = []
    for k in range(1, 12):
        frame = frame_at(k)
        vertices = sn.track(frame.image, vertices, model, PARAMS).vertices
        scores.append(polygon_iou(vertices, frame.patch_polygon, (480, 640)))
    assert min(scores) >= 0.95, scores


def test_reads_only_pixels_near_its_vertices(renderer, rng) -> None:
    frame = renderer.render(Scene(), T_WORLD_CAMERA, Lighting(noise_sigma=4.0), rng)
    seed = frame.patch_polygon.mean(axis=0)
    model = color.fit(sn.seed_samples(frame.image, seed, 5.0))
    result = sn.acquire(frame.image, seed, model, PARAMS)
    # Scribble the target color everywhere farther than the window from the final contour's
    # bounding box: the snake's path never read those pixels, so nothing may change.
    scribbled = frame.image.copy()
    low = np.floor(result.vertices.min(axis=0)).astype(int) - 2 * PARAMS.window_radius_px - 2
    high = np.ceil(result.vertices.max(axis=0)).astype(int) + 2 * PARAMS.window_radius_px + 2
    keep = np.zeros(scribbled.shape[:2], dtype=bool)
    keep[max(low[1], 0) : high[1], max(low[0], 0) : high[0]] = True
    scribbled[~keep] = (60, 170, 30)
    again = sn.acquire(scribbled, seed, model, PARAMS)
    np.testing.assert_array_equal(again.vertices, result.vertices)


def test_pressure_pushes_out_inside_and_in_outside() -> None:
    image = np.full((100, 100, 3), 200, dtype=np.uint8)
    image[30:70, 30:70] = (60, 170, 30)
    model = color.fit(image[40:60, 40:60])
    points = np.array([[50.0, 50.0], [10.0, 10.0], [30.0, 50.0], [29.5, 50.0]])
    p = sn.pressure(image, points, model, PARAMS)
    assert p[0] == pytest.approx(1.0)
    assert p[1] == pytest.approx(-1.0)
    # Pixel centre 30 is the first target column: a window centred on 29.5 is half target.
    assert p[3] == pytest.approx(0.0, abs=1e-9)
    assert 0.0 < p[2] < 1.0


def test_collapses_without_target(renderer, rng) -> None:
    frame = renderer.render(Scene(patch_present=False), T_WORLD_CAMERA, rng=rng)
    model = color.from_rgb((30, 170, 60))
    start = rectangle((320.0, 240.0), (120.0, 80.0))
    result = sn.evolve(frame.image, start, model, PARAMS)
    assert result.collapsed
    assert not result.converged


def test_parameter_validation() -> None:
    # the settings' rules are in their declaration (the snake's parameters are built from it)
    with pytest.raises(ValueError, match="min_segment_px"):
        SnakeSettings(min_segment_px=10.0, max_segment_px=5.0)
    with pytest.raises(ValueError, match="tension"):
        SnakeSettings(tension=0.8)
    with pytest.raises(ValueError, match="color image"):
        sn.evolve(
            np.zeros((10, 10), np.uint8),
            rectangle((5, 5), (4, 4)),
            color.from_rgb((1, 2, 3)),
            PARAMS,
        )
    with pytest.raises(ValueError, match="outside"):
        sn.seed_samples(np.zeros((10, 10, 3), np.uint8), (50.0, 50.0), 3.0)
