"""DigiCam through the module harness: real video files, bad sources, stale streams, the sim."""

from __future__ import annotations

import logging
import time

import cv2
import numpy as np
import pytest

from umbra.connectors import UserError
from umbra.connectors.messages import CameraModel, Pose
from umbra.modules.geometry.transforms import transform_points
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.scene import camera_looking_down, patch_outline, pose
from umbra.modules.vision.video import VideoWriter
from umbra.runtime.harness import ModuleHarness

FRAMES = 6


@pytest.fixture
def video(tmp_path):
    """A 6-frame MJPG file written by cv2.VideoWriter; frame k has blue level 40 k."""
    path = tmp_path / "clip.avi"
    with VideoWriter(path, 10.0, (160, 120)) as writer:
        for k in range(FRAMES):
            frame = np.zeros((120, 160, 3), dtype=np.uint8)
            frame[:] = (40 * k, 60, 220 - 30 * k)
            writer.write(frame)
    return path


def blue(sample) -> int:
    return round(float(np.median(sample.pixels[:, :, 0])) / 40.0)


def images(harness: ModuleHarness, steps: int, dt: float = 0.1) -> list:
    sent = []
    for _ in range(steps):
        sent.extend(harness.step(dt).get("image", []))
    return sent


def test_plays_a_video_file_in_order_and_loops(video) -> None:
    with ModuleHarness(DigiCam, {"source": str(video)}) as h:
        sent = images(h, 2 * FRAMES + 2)
    assert [blue(s) for s in sent] == [*range(FRAMES), *range(FRAMES), 0, 1]
    assert sent[0].pixels.shape == (120, 160, 3)
    assert not any(s.stale for s in sent)
    assert [s.seq for s in sent] == list(range(1, len(sent) + 1))


def test_file_resized_on_request(video) -> None:
    with ModuleHarness(DigiCam, {"source": str(video), "width": 80, "height": 60}) as h:
        first = h.step(0.1)["image"][0]
    assert first.pixels.shape == (60, 80, 3)


def test_file_that_ends_holds_then_goes_stale_once(video, caplog) -> None:
    params = {"source": str(video), "at_end": "hold", "stale_after": 0.5}
    with caplog.at_level(logging.WARNING), ModuleHarness(DigiCam, params) as h:
        sent = images(h, FRAMES + 20)
        summary = h.module.summary()
        assert h.stop_request is None
    fresh = [s for s in sent if not s.stale]
    stale = [s for s in sent if s.stale]
    assert len(fresh) == FRAMES
    assert len(stale) == 1
    np.testing.assert_array_equal(stale[0].pixels, fresh[-1].pixels)
    assert stale[0].stamp - fresh[-1].stamp >= 0.5 - 1e-9
    warnings = [r for r in caplog.records if "stale" in r.getMessage()]
    assert len(warnings) == 1
    assert summary == {"frames": FRAMES, "stale_events": 1}


def test_file_that_ends_can_stop_the_run(video) -> None:
    with ModuleHarness(DigiCam, {"source": str(video), "at_end": "stop"}) as h:
        sent = images(h, FRAMES + 2)
        assert h.stop_request is not None
        reason, code = h.stop_request
    assert len(sent) == FRAMES
    assert code == 0 and "ended" in reason


def test_stream_that_stops_delivering_is_marked_stale_and_the_run_goes_on(video) -> None:
    """A stream (here a file:// URL) is read for its latest frame; when it dries up, the last
    frame is sent once more marked stale, and the module keeps stepping."""
    params = {"source": video.resolve().as_uri(), "stale_after": 0.3}
    with ModuleHarness(DigiCam, params) as h:
        deadline = time.monotonic() + 5.0
        sent = []
        while time.monotonic() < deadline and not any(s.stale for s in sent):
            sent.extend(h.step(0.05).get("image", []))
            time.sleep(0.01)
        later = images(h, 10, 0.05)
        assert h.stop_request is None
    assert any(not s.stale for s in sent)
    assert sum(s.stale for s in sent) == 1
    assert later == []  # said once; nothing new to send


@pytest.mark.parametrize(
    ("source", "words"),
    [
        ("/no/such/clip.avi", "no such file"),
        ("/", "a folder"),
        ("9", "cannot open camera device 9"),
    ],
)
def test_unusable_sources_are_user_errors_at_start(source: str, words: str) -> None:
    """A missing file or a folder is refused with the parameters (so ``umbra check`` says it);
    a device is known only when it is opened."""
    with pytest.raises(UserError, match=words):
        ModuleHarness(DigiCam, {"source": source}).start()


def test_undecodable_file_is_a_user_error(tmp_path) -> None:
    path = tmp_path / "broken.avi"
    path.write_bytes(b"not a video at all" * 64)
    with pytest.raises(UserError, match=r"broken\.avi"):
        ModuleHarness(DigiCam, {"source": str(path)}).start()


def test_width_without_height_is_a_user_error() -> None:
    with pytest.raises(UserError, match="both width and height"):
        ModuleHarness(DigiCam, {"width": 320}).start()


# -- simulated camera ---------------------------------------------------------------------------


def expected_corners(T_world_camera: np.ndarray, fx: float = 600.0) -> np.ndarray:
    corners = transform_points(pose((0.0, 0.0, 0.03)), patch_outline((0.06, 0.04), 1))
    T_camera_world = np.linalg.inv(T_world_camera)
    rvec, _ = cv2.Rodrigues(T_camera_world[:3, :3])
    K = np.array([[fx, 0, 320.0], [0, fx, 240.0], [0, 0, 1]])
    pixels, _ = cv2.projectPoints(corners, rvec, T_camera_world[:3, 3], K, np.zeros(5))
    return pixels.reshape(-1, 2)


def test_sim_renders_the_patch_with_ground_truth() -> None:
    with ModuleHarness(DigiCam, {"noise_sigma": 4.0}) as h:
        out = h.step(0.1)
    image, truth = out["image"][0], out["truth"][0]
    assert image.pixels.shape == (480, 640, 3) and image.frame == "camera"
    np.testing.assert_allclose(
        truth.vertices[::16], expected_corners(camera_looking_down((0, 0, 0.03), 0.22)), atol=1e-6
    )
    assert truth.status == "tracking"
    # The centre of the patch has the patch's color (RGB 30, 170, 60).
    np.testing.assert_allclose(
        image.pixels[235:245, 315:325].mean(axis=(0, 1)), [60, 170, 30], atol=3
    )


def test_sim_follows_the_camera_pose_and_model_inputs() -> None:
    T_world_camera = camera_looking_down((0.01, -0.005, 0.03), 0.3)
    with ModuleHarness(DigiCam, {}) as h:
        h.push("camera_pose", Pose(matrix=T_world_camera, parent="world", child="camera"))
        truth = h.step(0.1)["truth"][0]
        np.testing.assert_allclose(
            truth.vertices[::16], expected_corners(T_world_camera), atol=1e-6
        )
        h.push("camera_model", CameraModel(fx=1200.0, fy=1200.0, u0=320.0, v0=240.0))
        zoomed = h.step(0.1)["truth"][0]
        np.testing.assert_allclose(
            zoomed.vertices[::16], expected_corners(T_world_camera, 1200.0), atol=1e-6
        )
        assert zoomed.area == pytest.approx(4 * truth.area, rel=1e-6)


def test_sim_composes_a_mount_pose_with_static_frames() -> None:
    T_tool_camera = pose((0.0, 0.02, 0.0))
    T_world_camera = camera_looking_down((0.0, 0.0, 0.03), 0.25)
    T_base_tool = T_world_camera @ np.linalg.inv(T_tool_camera)
    frames = {"world->base": np.eye(4), "tool->camera": T_tool_camera}
    with ModuleHarness(DigiCam, {}, frames=frames) as h:
        h.push("camera_pose", Pose(matrix=T_base_tool, parent="base", child="tool"))
        truth = h.step(0.1)["truth"][0]
    np.testing.assert_allclose(truth.vertices[::16], expected_corners(T_world_camera), atol=1e-6)


def test_sim_pose_without_a_frame_chain_is_a_user_error() -> None:
    with ModuleHarness(DigiCam, {}) as h:
        h.push("camera_pose", Pose(matrix=np.eye(4), parent="base", child="tool"))
        with pytest.raises(UserError, match="world->base"):
            h.step(0.1)


def test_sim_patch_removed_gives_idle_truth() -> None:
    with ModuleHarness(DigiCam, {"patch_present": False}) as h:
        truth = h.step(0.1)["truth"][0]
    assert truth.status == "idle" and truth.vertices.shape == (0, 2)


def test_sim_noise_is_reproducible_from_the_graph_seed() -> None:
    def first(seed: int) -> np.ndarray:
        with ModuleHarness(DigiCam, {"noise_sigma": 5.0}, seed=seed) as h:
            return h.step(0.1)["image"][0].pixels

    np.testing.assert_array_equal(first(3), first(3))
    assert np.count_nonzero(first(3) != first(4)) > 100_000


def test_bad_sim_parameters_are_user_errors() -> None:
    with pytest.raises(UserError, match="patch_rgb"):
        ModuleHarness(DigiCam, {"patch_rgb": [300, 0, 0]}).start()
