"""vsSnake through the module harness, fed by the simulated DigiCam."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from umbra.connectors import UserError
from umbra.connectors.commands import Seed
from umbra.connectors.messages import Image, Pose
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.metrics import polygon_iou
from umbra.modules.vision.scene import pose
from umbra.modules.vision.vs_snake import VsSnake
from umbra.runtime.harness import ModuleHarness


def camera(**params) -> ModuleHarness:
    return ModuleHarness(DigiCam, {"noise_sigma": 6.0, "patch_yaw_deg": 25.0, **params}).start()


def frame(cam: ModuleHarness, dt: float = 1 / 30) -> tuple[Image, object]:
    out = cam.step(dt)
    return out["image"][0], out["truth"][0]


def test_point_seed_tracks_the_patch_and_reports_features() -> None:
    cam = camera()
    image, truth = frame(cam)
    with ModuleHarness(
        VsSnake, {"seed_uv": (truth.centroid + np.array([12.0, -6.0])).tolist()}
    ) as h:
        for k in range(6):
            # The patch slides 3 mm (about 8 px) per frame.
            cam.push(
                "patch_pose",
                Pose(
                    matrix=pose((0.003 * k, 0.0, 0.03), np.deg2rad(25 + 2 * k)),
                    parent="world",
                    child="patch",
                ),
            )
            image, truth = frame(cam)
            h.push("image", image)
            contour = h.step(1 / 30)["contour"][0]
            assert contour.status == "tracking", contour.reason
            assert polygon_iou(contour.vertices, truth.vertices, (480, 640)) >= 0.95
            np.testing.assert_allclose(contour.centroid, truth.centroid, atol=1.5)
            assert contour.area == pytest.approx(truth.area, rel=0.05)
            assert abs(contour.orientation - truth.orientation) < np.deg2rad(1.5)
            np.testing.assert_allclose(contour.axes, truth.axes, rtol=0.05)
            assert contour.stamp == image.stamp
        summary = h.module.summary()
    assert summary["frames"] == 6 and summary["failures"] == 0


@pytest.mark.parametrize(("width", "height"), [(1280, 720), (1920, 1080)])
def test_tracks_from_a_high_resolution_simulated_camera(width: int, height: int) -> None:
    """DigiCam renders 720p and 1080p frames (same field of view as 640x480 at fx 600); the
    snake tracks the moving patch in them, its contour on the truth to IoU 0.99."""
    f = 600.0 * width / 640.0
    cam = camera(width=width, height=height, fx=f, fy=f, u0=width / 2, v0=height / 2)
    image, truth = frame(cam)
    assert image.pixels.shape == (height, width, 3)
    with ModuleHarness(VsSnake, {"seed_uv": truth.centroid.tolist()}) as h:
        for k in range(4):
            cam.push(
                "patch_pose",
                Pose(
                    matrix=pose((0.002 * k, 0.0, 0.03), np.deg2rad(25 + 2 * k)),
                    parent="world",
                    child="patch",
                ),
            )
            image, truth = frame(cam)
            h.push("image", image)
            contour = h.step(1 / 30)["contour"][0]
            assert contour.status == "tracking", contour.reason
            assert polygon_iou(contour.vertices, truth.vertices, (height, width)) >= 0.99
            assert contour.area == pytest.approx(truth.area, rel=0.01)


def test_region_seed_with_a_target_color() -> None:
    image, truth = frame(camera())
    params = {
        "seed_mode": "region",
        "seed_region": [180, 110, 460, 370],
        "target_rgb": [30, 170, 60],
    }
    with ModuleHarness(VsSnake, params) as h:
        h.push("image", image)
        contour = h.step(0.1)["contour"][0]
    assert contour.status == "tracking"
    assert polygon_iou(contour.vertices, truth.vertices, (480, 640)) >= 0.95


def test_waits_for_the_operator_seed_then_reseeds() -> None:
    image, truth = frame(camera())
    with ModuleHarness(VsSnake, {"seed_mode": "none"}) as h:
        h.push("image", image)
        idle = h.step(0.1)["contour"][0]
        assert idle.status == "idle" and "seed" in idle.reason
        h.push("seed", Seed.point(*truth.centroid))
        h.push("image", image)
        contour = h.step(0.1)["contour"][0]
        assert contour.status == "tracking"
        assert polygon_iou(contour.vertices, truth.vertices, (480, 640)) >= 0.95
        # A seed on the gray tray: the learned color is the tray's, not the patch's.
        h.push("seed", Seed.box(40.0, 40.0, 140.0, 120.0))
        h.push("image", image)
        elsewhere = h.step(0.1)["contour"][0]
        assert polygon_iou(elsewhere.vertices, truth.vertices, (480, 640)) < 0.5


def test_failure_latches_and_is_reported_once(caplog) -> None:
    cam = camera()
    image, truth = frame(cam)
    with (
        caplog.at_level(logging.WARNING),
        ModuleHarness(VsSnake, {"seed_uv": truth.centroid.tolist()}) as h,
    ):
        h.push("image", image)
        assert h.step(0.1)["contour"][0].status == "tracking"
        gone = camera(patch_present=False)
        statuses = []
        for _ in range(3):
            h.push("image", frame(gone)[0])
            statuses.append(h.step(0.1)["contour"][0])
        assert [c.status for c in statuses] == ["failed"] * 3
        assert "area changed" in statuses[0].reason
        assert statuses[2].reason == statuses[0].reason
        assert h.module.summary()["failures"] == 1
    assert len([r for r in caplog.records if "snake failed" in r.getMessage()]) == 1


def test_stale_image_fails_without_touching_the_snake() -> None:
    image, truth = frame(camera())
    with ModuleHarness(VsSnake, {"seed_uv": truth.centroid.tolist()}) as h:
        h.push("image", image)
        tracked = h.step(0.1)["contour"][0]
        h.push("image", Image(pixels=image.pixels, stale=True))
        stale = h.step(0.1)["contour"][0]
        assert stale.status == "failed" and "stale" in stale.reason
        h.push("image", image)
        again = h.step(0.1)["contour"][0]
    assert again.status == "tracking"
    assert again.area == pytest.approx(tracked.area, rel=0.02)


def test_no_output_without_a_new_image() -> None:
    image, truth = frame(camera())
    with ModuleHarness(VsSnake, {"seed_uv": truth.centroid.tolist()}) as h:
        h.push("image", image)
        assert "contour" in h.step(0.1)
        assert h.step(0.1) == {}


@pytest.mark.parametrize(
    ("params", "words"),
    [
        ({"min_segment_px": 20.0, "max_segment_px": 10.0}, "min_segment_px"),
        ({"seed_uv": [1.0, 2.0, 3.0]}, "seed_uv"),
        ({"seed_mode": "region", "seed_region": [50, 50, 10, 10]}, "empty region"),
        ({"target_rgb": [10, 20]}, "target_rgb"),
        ({"tension": 0.9}, "tension"),
    ],
)
def test_bad_parameters_are_user_errors(params, words) -> None:
    with pytest.raises(UserError, match=words):
        ModuleHarness(VsSnake, params).start()


def test_a_single_channel_image_fails_the_snake_not_the_run() -> None:
    """A grayscale camera (H x W uint8) gives a failed, empty contour with the reason."""
    with ModuleHarness(VsSnake, {}) as h:
        h.push("image", Image(pixels=np.full((48, 64), 128, dtype=np.uint8)))
        out = h.step(0.1)["contour"][0]
        assert out.status == "failed"
        assert "grayscale image" in out.reason
        assert len(out.vertices) == 0
        assert h.module.summary()["failures"] == 1


def test_a_float_image_is_a_user_error() -> None:
    with ModuleHarness(VsSnake, {}) as h:
        h.push("image", Image(pixels=np.zeros((48, 64, 3), dtype=np.float32)))
        with pytest.raises(UserError, match="H x W x 3 uint8"):
            h.step(0.1)
