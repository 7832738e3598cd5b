"""A snake that cannot be on a target says `failed` with the reason: a featureless image, a
grayscale image, a contour cut by the image border, a snake that never settles."""

from __future__ import annotations

import cv2
import numpy as np

from umbra.connectors.tracking import SnakeCheck
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.scene import Scene, pose
from umbra.modules.vision.snake import SnakeParams
from umbra.modules.vision.tracker import SnakeTracker

from .conftest import METRES_PER_PIXEL, T_WORLD_CAMERA

LIGHTING = Lighting(noise_sigma=6.0, blur_length_px=1.0)


def render(renderer, scene: Scene, seed: int = 4) -> tuple[np.ndarray, np.ndarray]:
    frame = renderer.render(scene, T_WORLD_CAMERA, LIGHTING, np.random.default_rng(seed))
    return frame.image, frame.patch_polygon


def test_a_patch_in_view_is_tracking(renderer) -> None:
    """The control case of the tests below: the same scene, the patch wholly in view."""
    image, polygon = render(renderer, Scene(background="photo"))
    tracker = SnakeTracker()
    tracker.seed_at_point(image, polygon.mean(axis=0))
    update = tracker.update(image)
    assert update.status == "tracking", update.sanity.reason
    assert update.converged


def test_a_featureless_image_fails() -> None:
    """One colour everywhere: the snake grows to the border and finds no edge."""
    rng = np.random.default_rng(2)
    noise = rng.normal(0.0, 4.0, (240, 320, 3))
    image = np.clip(np.array([60, 170, 30]) + noise, 0, 255).astype(np.uint8)
    tracker = SnakeTracker()
    tracker.seed_at_point(image, (160, 120))
    update = tracker.update(image)
    assert update.status == "failed"
    assert "no colour edge under" in update.sanity.reason
    assert "touches the image border" in update.sanity.reason
    assert update.sanity.checks[:2] == (SnakeCheck.NO_EDGE, SnakeCheck.TOUCHES_BORDER)


def test_a_grayscale_image_fails_without_growing(renderer) -> None:
    image, polygon = render(renderer, Scene(background="photo"))
    gray = cv2.cvtColor(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    tracker = SnakeTracker()
    tracker.seed_at_point(gray, polygon.mean(axis=0))
    update = tracker.update(gray)
    assert update.status == "failed"
    assert "target colour is gray" in update.sanity.reason
    assert update.sanity.checks[0] == SnakeCheck.GRAY_TARGET
    assert update.iterations == 0


def test_a_patch_cut_by_the_image_border_fails(renderer) -> None:
    # The patch centre 0.1 m to the side: 273 px right of the image centre, past the border.
    image, polygon = render(renderer, Scene(T_world_patch=pose((0.1, 0.0, 0.03), 0.0)))
    visible = polygon[polygon[:, 0] < 630]
    tracker = SnakeTracker()
    tracker.seed_at_point(image, (visible[:, 0].min() + 25.0, visible[:, 1].mean()))
    update = tracker.update(image)
    assert update.status == "failed"
    assert "touches the image border" in update.sanity.reason
    assert update.vertices[:, 0].max() > 637.0


def test_an_acquisition_that_does_not_converge_fails(renderer) -> None:
    image, polygon = render(renderer, Scene(background="photo"))
    tracker = SnakeTracker(SnakeParams(max_iterations=8))
    tracker.seed_at_point(image, polygon.mean(axis=0))
    update = tracker.update(image)
    assert not update.converged
    assert update.status == "failed"
    assert "snake did not converge in 8 iterations" in update.sanity.reason


def test_a_snake_that_never_settles_while_tracking_fails(renderer) -> None:
    """One iteration per frame behind a patch that slides 6 px per frame: the snake is pushed
    at full pressure every frame and fails after max_unconverged_frames; with the default
    budget it keeps up and tracks."""

    def frames():
        for k in range(9):
            xy = (-0.01 + 6.0 * METRES_PER_PIXEL * k, 0.0, 0.03)
            yield render(renderer, Scene(T_world_patch=pose(xy, 0.1), background="photo"), k)

    outcomes = {}
    for name, params in (
        ("starved", SnakeParams(track_iterations=1, max_unconverged_frames=3)),
        ("default", SnakeParams(max_unconverged_frames=3)),
    ):
        tracker = SnakeTracker(params)
        statuses = []
        for k, (image, polygon) in enumerate(frames()):
            if k == 0:
                tracker.seed_at_point(image, polygon.mean(axis=0))
            update = tracker.update(image)
            statuses.append((update.status, update.sanity.reason))
        outcomes[name] = statuses
    assert all(status == "tracking" for status, _ in outcomes["default"]), outcomes["default"]
    starved = outcomes["starved"]
    assert [status for status, _ in starved[:3]] == ["tracking"] * 3
    assert starved[3][0] == "failed"
    assert "snake did not converge for 3 frames in a row" in starved[3][1]
