"""``umbra snake IMAGE --seed U,V`` end to end through the CLI entry point."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics
from umbra.modules.vision.features import polygon_features
from umbra.modules.vision.lighting import Lighting
from umbra.modules.vision.metrics import polygon_iou
from umbra.modules.vision.scene import Scene, SceneRenderer, pose
from umbra.runtime.cli.main import main

from .conftest import DISTORTION, T_WORLD_CAMERA


@pytest.fixture(scope="module")
def patch_image(tmp_path_factory, renderer):
    frame = renderer.render(
        Scene(T_world_patch=pose((0.004, 0.002, 0.03), np.deg2rad(30))),
        T_WORLD_CAMERA,
        Lighting(noise_sigma=5.0),
        np.random.default_rng(2),
    )
    path = tmp_path_factory.mktemp("snake") / "patch.png"
    cv2.imwrite(str(path), frame.image)
    return path, frame


def test_json_result_matches_the_ground_truth(patch_image, capsys) -> None:
    path, frame = patch_image
    u, v = frame.patch_polygon.mean(axis=0) + np.array([6.0, 4.0])
    code = main(["snake", str(path), "--seed", f"{u:.1f},{v:.1f}", "--json"])
    result = json.loads(capsys.readouterr().out)
    assert code == 0
    assert result["status"] == "tracking" and result["reason"] == ""
    truth = polygon_features(frame.patch_polygon)
    np.testing.assert_allclose(result["centroid"], truth.centroid_uv, atol=0.5)
    assert result["area"] == pytest.approx(truth.area_px2, rel=0.04)
    assert result["orientation_deg"] == pytest.approx(np.rad2deg(truth.orientation_rad), abs=1.0)
    assert polygon_iou(np.array(result["polygon"]), frame.patch_polygon, (480, 640)) >= 0.95
    assert result["iterations"] > 10 and result["converged"] is True
    assert 0 < result["time_ms"] < 10_000


def test_human_output_settings_and_overlay(patch_image, capsys, tmp_path) -> None:
    path, frame = patch_image
    u, v = frame.patch_polygon.mean(axis=0)
    out_png = tmp_path / "drawn.png"
    code = main(
        ["snake", str(path), "--seed", f"{u},{v}", "--set", "k_sigma=3.5",
         "--set", "track_iterations=5", "--overlay", str(out_png)]
    )  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0
    assert "tracking" in text and "centroid" in text and "vertices" in text
    drawn = cv2.imread(str(out_png))
    assert drawn.shape == (480, 640, 3)
    assert np.count_nonzero(np.any(drawn != cv2.imread(str(path)), axis=2)) > 500


def test_a_seed_off_the_patch_fails_the_checks_with_exit_1(patch_image, capsys) -> None:
    path, _ = patch_image
    code = main(["snake", str(path), "--seed", "20,20", "--json", "--set", "max_iterations=60"])
    result = json.loads(capsys.readouterr().out)
    assert code == 1
    assert result["status"] == "failed" and result["reason"]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--seed", "1"], "--seed expects U,V"),
        (["--seed", "900,10"], "outside the 640x480 image"),
        (["--seed", "320,240", "--set", "kk=1"], "unknown parameter `kk`"),
        (
            ["--seed", "320,240", "--set", "step_px=fast"],
            "parameter `step_px`: Input should be a valid number",
        ),
        (["--seed", "320,240", "--overlay", "/no/such/dir/x.png"], "cannot write"),
    ],
)
def test_bad_input_exits_2_with_a_message(patch_image, capsys, args, words) -> None:
    path, _ = patch_image
    assert main(["snake", str(path), *args]) == 2
    assert words in capsys.readouterr().err


def test_unreadable_image_exits_2(tmp_path, capsys) -> None:
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"no image here")
    assert main(["snake", str(bad), "--seed", "1,1"]) == 2
    assert "cannot read it as an image" in capsys.readouterr().err
    assert main(["snake", str(tmp_path / "missing.png"), "--seed", "1,1"]) == 2
    assert "cannot read image file: no such file" in capsys.readouterr().err


@pytest.mark.parametrize(("width", "height"), [(1280, 720), (1920, 1080)])
def test_high_resolution_images(width: int, height: int, tmp_path, capsys) -> None:
    """The same patch through a 720p and a 1080p camera (same field of view as the 640x480 one):
    tracking, area within 0.5 % of the truth. The snake works on a coarser grid (σ = 2 at
    720p, 3 at 1080p: a contour of 1100-1600 px); at σ = 2 its outline is measured at the full
    grid's spacing (a point every 7-10 px), at σ = 3 at its own (fewer than 100 points)."""
    f = 600.0 * width / 640.0
    renderer = SceneRenderer(
        Intrinsics(f, f, 0.0, width / 2, height / 2, width, height), DISTORTION
    )
    frame = renderer.render(
        Scene(T_world_patch=pose((0.004, 0.002, 0.03), np.deg2rad(30)), background="photo"),
        T_WORLD_CAMERA,
        Lighting(noise_sigma=5.0, blur_length_px=2.0),
        np.random.default_rng(3),
    )
    path = tmp_path / "patch.png"
    cv2.imwrite(str(path), frame.image)
    u, v = frame.patch_polygon.mean(axis=0)
    code = main(["snake", str(path), "--seed", f"{u:.1f},{v:.1f}", "--json"])
    result = json.loads(capsys.readouterr().out)
    assert code == 0, result["reason"]
    assert result["status"] == "tracking"
    truth = polygon_features(frame.patch_polygon)
    assert result["area"] == pytest.approx(truth.area_px2, rel=0.005)
    assert polygon_iou(np.array(result["polygon"]), frame.patch_polygon, (height, width)) > 0.99
    perimeter = float(
        np.sum(np.hypot(*np.diff(frame.patch_polygon, axis=0, append=frame.patch_polygon[:1]).T))
    )
    if width == 1280:
        assert 7.0 <= perimeter / len(result["polygon"]) <= 10.0
    else:
        assert len(result["polygon"]) < 100
