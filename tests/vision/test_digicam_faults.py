"""Scheduled faults of the simulated DigiCam (failure-injection trials), through the harness.

Every faulted camera runs beside a fault-free twin with the same seed and inputs, so "before
the fault the images are unchanged" is an exact comparison, and the effect of the fault is read
from pixel colors against the ground-truth outline of the patch.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from umbra.connectors import UserError
from umbra.connectors.messages import Image, Pose
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.scene import camera_looking_down
from umbra.modules.vision.sim_camera import OCCLUDER_GAP_M, OCCLUDER_LIFT_M
from umbra.modules.vision.vs_snake import VsSnake
from umbra.runtime.graph.check import check_text
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry
from umbra.runtime.scheduler import Scheduler, SchedulerOptions

REPO = Path(__file__).resolve().parents[2]

DT = 1 / 30
FAULT_AT_S = 0.2
#: The harness steps the clock before each step: the first frame is at DT, the fault at the
#: first frame whose time since then reaches FAULT_AT_S (frame index 6 at 30 Hz).
FIRST_FAULTED = 6
PATCH_BGR = np.array([60, 170, 30])  # patch_rgb 30, 170, 60
SKIN_BGR = np.array([150, 180, 225])  # fault_rgb 225, 180, 150


def cameras(fault: str, **params) -> tuple[ModuleHarness, ModuleHarness]:
    """A faulted camera and its fault-free twin (same seed, same parameters otherwise)."""
    base = {"fault_at_s": FAULT_AT_S, **params}
    return (
        ModuleHarness(DigiCam, {**base, "fault": fault}, seed=5).start(),
        ModuleHarness(DigiCam, {**base, "fault": "none"}, seed=5).start(),
    )


def inside(polygon: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Boolean mask of the pixels whose centres lie inside ``polygon`` (N x 2 px)."""
    mask = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(polygon * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    return mask.astype(bool)


def near(pixels: np.ndarray, bgr: np.ndarray, tolerance: float = 12.0) -> np.ndarray:
    """Pixels within ``tolerance`` gray levels of ``bgr`` in every channel."""
    return np.all(np.abs(pixels.astype(int) - bgr) <= tolerance, axis=2)


def test_before_the_fault_every_kind_renders_the_fault_free_images() -> None:
    for kind in ("occluder", "remove_patch", "distractor", "freeze"):
        faulted, plain = cameras(kind, noise_sigma=5.0, patch_yaw_deg=15.0)
        for k in range(FIRST_FAULTED + 1):
            a, b = faulted.step(DT), plain.step(DT)
            same = np.array_equal(a["image"][0].pixels, b["image"][0].pixels)
            # Up to the fault the same pixels (noise included); at it, a different image.
            assert same == (k < FIRST_FAULTED), (kind, k)
            if k < FIRST_FAULTED:
                assert faulted.module.summary()["fault_started_at"] is None
        summary = faulted.module.summary()
        assert summary["fault"] == kind
        assert summary["fault_started_at"] == pytest.approx(DT * (FIRST_FAULTED + 1))
        assert plain.module.summary()["fault_started_at"] is None


def test_occluder_covers_a_growing_share_of_the_patch() -> None:
    speed = 0.05
    faulted, plain = cameras("occluder", fault_speed_mps=speed)
    shares, expected = [], []
    for _ in range(45):
        out = faulted.step(DT)
        truth_plain = plain.step(DT)["truth"][0]
        image, truth = out["image"][0], out["truth"][0]
        # The truth is still the whole patch: the occluder hides it, it does not move it.
        np.testing.assert_allclose(truth.vertices, truth_plain.vertices)
        patch = inside(truth.vertices, image.pixels.shape[:2])
        shares.append(np.count_nonzero(near(image.pixels, SKIN_BGR) & patch) / patch.sum())
        started = faulted.module.summary()["fault_started_at"]
        since = 0.0 if started is None else faulted.now - started
        # From the +y side (image top at yaw 0), across the 0.04 m side of the patch.
        expected.append(float(np.clip((speed * since - OCCLUDER_GAP_M) / 0.04, 0.0, 1.0)))
    shares, expected = np.array(shares), np.array(expected)
    assert np.all(shares[: FIRST_FAULTED + 1] == 0.0)  # before, and just outside at the start
    assert np.all(np.diff(shares) >= -1e-3)
    np.testing.assert_allclose(shares, expected, atol=0.03)
    half = faulted.module.summary()["fault_started_at"] + 1.0
    assert shares[round(half / DT) - 1] >= 0.5  # at least half covered 1 s after the start
    assert shares[-1] > 0.97  # then it stays, covering the patch


def test_occluder_is_visible_just_outside_the_patch_when_the_fault_begins() -> None:
    faulted, plain = cameras("occluder", fault_side="-x")
    for _ in range(FIRST_FAULTED + 1):
        out, ref = faulted.step(DT), plain.step(DT)
    image, truth = out["image"][0].pixels, out["truth"][0]
    skin = near(image, SKIN_BGR)
    assert not np.any(skin & inside(truth.vertices, image.shape[:2]))
    # -x is the image left at yaw 0: the slab's leading edge is 5 mm left of the patch (0.03 m
    # from its centre), OCCLUDER_LIFT_M nearer the camera 0.22 m above the patch.
    leading_edge_u = 320.0 - 600.0 * (0.03 + OCCLUDER_GAP_M) / (0.22 - OCCLUDER_LIFT_M)
    columns = np.flatnonzero(skin.any(axis=0))
    assert columns.max() + 0.5 == pytest.approx(leading_edge_u, abs=1.0)
    assert truth.vertices[:, 0].min() - leading_edge_u > 10.0
    assert np.count_nonzero(image != ref["image"][0].pixels) > 1000


def test_remove_patch_takes_the_patch_pixels_away_and_leaves_the_tool() -> None:
    faulted, plain = cameras("remove_patch")
    for k in range(FIRST_FAULTED + 3):
        out, ref = faulted.step(DT), plain.step(DT)
        truth = ref["truth"][0]
        # The patch less its border pixels (partly covered, blended with the tool).
        patch = cv2.erode(inside(truth.vertices, (480, 640)).astype(np.uint8), None) > 0
        green = near(out["image"][0].pixels, PATCH_BGR)
        if k < FIRST_FAULTED:
            assert green[patch].mean() > 0.99
            assert out["truth"][0].status == "tracking"
        else:
            assert not green.any()
            assert out["truth"][0].status == "idle" and len(out["truth"][0].vertices) == 0
            # Where the patch was, the tool body (RGB 70, 72, 78) shows.
            tool = near(out["image"][0].pixels, np.array([78, 72, 70]))
            assert tool[patch].mean() > 0.99


def test_distractor_adds_a_same_color_patch_touching_the_patch() -> None:
    faulted, plain = cameras("distractor", patch_yaw_deg=10.0, fault_side="+x")
    for k in range(FIRST_FAULTED + 2):
        out, ref = faulted.step(DT), plain.step(DT)
        image, truth = out["image"][0].pixels, out["truth"][0]
        np.testing.assert_allclose(truth.vertices, ref["truth"][0].vertices)
        green = near(image, PATCH_BGR, 20.0).astype(np.uint8)
        _, labels = cv2.connectedComponents(green, connectivity=4)
        u, v = np.round(truth.centroid).astype(int)
        blob = labels == labels[v, u]
        patch = inside(truth.vertices, image.shape[:2])
        outside = np.count_nonzero(blob & ~patch)
        if k < FIRST_FAULTED:
            assert outside < 0.02 * patch.sum()
        else:
            # One connected same-color region: the patch and a second patch as large.
            assert outside == pytest.approx(patch.sum(), rel=0.05)
            assert np.count_nonzero(green) == pytest.approx(2 * patch.sum(), rel=0.05)


@pytest.mark.parametrize("stale", [False, True])
def test_freeze_resends_the_last_frame_while_the_camera_moves(stale: bool) -> None:
    with ModuleHarness(
        DigiCam,
        {"fault": "freeze", "fault_at_s": FAULT_AT_S, "noise_sigma": 4.0,
         "fault_frozen_stale": stale},
    ) as h:  # fmt: skip
        images, truths = [], []
        for k in range(FIRST_FAULTED + 5):
            T = camera_looking_down((0.002 * k, 0.0, 0.03), 0.22)
            h.push("camera_pose", Pose(matrix=T, parent="world", child="camera"))
            out = h.step(DT)
            images.append(out["image"][0])
            truths.append(out["truth"][0])
        summary = h.module.summary()
    before, after = images[:FIRST_FAULTED], images[FIRST_FAULTED:]
    for a, b in itertools.pairwise(before):
        assert np.count_nonzero(a.pixels != b.pixels) > 1000  # a live, moving camera
    for frame in after:
        np.testing.assert_array_equal(frame.pixels, before[-1].pixels)
        assert frame.stale is stale
    assert not any(frame.stale for frame in before)
    stamps = [frame.stamp for frame in images]
    assert np.all(np.diff(stamps) > 0)  # frozen pixels, new stamps
    # The ground truth follows the world: the patch moves left 2 mm (5.5 px) per frame.
    moves = np.diff([t.centroid[0] for t in truths])
    np.testing.assert_allclose(moves, -0.002 * 600 / 0.22, rtol=1e-3)
    assert all("frozen" in t.reason for t in truths[FIRST_FAULTED:])
    assert summary["frames"] == len(images)
    assert summary["fault_started_at"] == pytest.approx(stamps[FIRST_FAULTED])


def test_freeze_from_the_first_frame_holds_the_first_frame() -> None:
    with ModuleHarness(DigiCam, {"fault": "freeze", "fault_at_s": 0.0, "noise_sigma": 4.0}) as h:
        frames = [h.step(DT)["image"][0] for _ in range(4)]
        assert h.module.summary()["fault_started_at"] == pytest.approx(DT)
    for frame in frames[1:]:
        np.testing.assert_array_equal(frame.pixels, frames[0].pixels)


@pytest.mark.parametrize(
    ("kind", "within"),
    # The occluder starts 5 mm outside the patch and the snake fails when the visible part's
    # aspect ratio has drifted 25 % (about 8 mm covered at 0.05 m/s): some 8 frames.
    [("occluder", 12), ("remove_patch", 2), ("distractor", 2)],
)
def test_snake_fails_within_a_few_frames_of_the_fault(kind: str, within: int) -> None:
    cam = ModuleHarness(
        DigiCam,
        {"fault": kind, "fault_at_s": FAULT_AT_S, "noise_sigma": 6.0, "patch_yaw_deg": 25.0},
    ).start()
    first = cam.step(DT)
    with ModuleHarness(VsSnake, {"seed_uv": first["truth"][0].centroid.tolist()}) as snake:
        statuses = []
        image: Image = first["image"][0]
        for _ in range(FIRST_FAULTED + within + 3):
            snake.push("image", image)
            statuses.append(snake.step(DT)["contour"][0].status)
            image = cam.step(DT)["image"][0]
        failures = snake.module.summary()["failures"]
    # Image k is the camera's k-th frame: tracking up to the fault, failed soon after, latched.
    assert statuses[:FIRST_FAULTED] == ["tracking"] * FIRST_FAULTED
    failed_at = statuses.index("failed")
    assert FIRST_FAULTED <= failed_at < FIRST_FAULTED + within
    assert set(statuses[failed_at:]) == {"failed"}
    assert failures == 1


def test_fault_parameters_are_checked() -> None:
    with pytest.raises(UserError, match="fault_at_s"):
        ModuleHarness(DigiCam, {"fault": "occluder", "fault_at_s": -1.0})
    with pytest.raises(UserError, match="fault_rgb"):
        ModuleHarness(DigiCam, {"fault": "occluder", "fault_rgb": [0, 0]}).start()
    with pytest.raises(UserError, match="needs source `sim`"):
        ModuleHarness(DigiCam, {"source": "0", "fault": "freeze"}).start()
    with pytest.raises(UserError, match="fault_speed_mps"):
        ModuleHarness(DigiCam, {"fault": "occluder", "fault_speed_mps": 0.0})


def test_summary_without_a_fault() -> None:
    with ModuleHarness(DigiCam, {}) as h:
        h.run(3, DT)
        summary = h.module.summary()
    assert summary == {
        "frames": 3,
        "stale_events": 0,
        "renderers_built": 1,
        "fault": "none",
        "fault_started_at": None,
    }


# -- in a graph: one process on the sim clock, and split over two processes --------------------

GRAPH = """\
graph: fault_trial
seed: 1
clock: {clock}
duration: {duration}
processes: {{umbra: {{}}, smart: {{}}}}
modules:
  cam:
    type: DigiCam
    process: umbra
    rate: 30
    params: {{noise_sigma: 6, patch_yaw_deg: 20, fault: remove_patch, fault_at_s: 0.5}}
  snake: {{type: vsSnake, process: smart, params: {{seed_uv: [322, 236]}}}}
connections:
  - cam.image -> snake.image
"""


def test_fault_in_a_graph_on_the_sim_clock(tmp_path) -> None:
    registry = Registry()
    for cls in (DigiCam, VsSnake):
        registry.add(cls)
    plan = check_text(GRAPH.format(clock="sim", duration=1.0), "fault.yaml", registry)
    options = SchedulerOptions(clock="sim", duration=1.0, output_dir=tmp_path)
    scheduler = Scheduler(plan, options)
    scheduler.run()
    cam, snake = scheduler.modules["cam"], scheduler.modules["snake"]
    started = cam.summary()["fault_started_at"]
    first = cam.image.last.stamp - (cam.summary()["frames"] - 1) / 30  # frames 1/30 s apart
    assert started == pytest.approx(first + 0.5, abs=1e-6)
    assert snake.summary()["failures"] == 1
    assert snake.contour.last.status == "failed"


@pytest.mark.slow  # two processes on the real clock: about 5 s
def test_fault_in_a_graph_split_over_two_processes(tmp_path) -> None:
    """The same graph with the camera and the snake in two processes (zenoh, real clock): the
    fault is driven by the camera's parameters and clock alone, so it plays the same."""
    (tmp_path / "fault.yaml").write_text(GRAPH.format(clock="real", duration=2.5))
    path = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env = dict(os.environ, PYTHONPATH=path, PYTHONUNBUFFERED="1")
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "run", "fault.yaml", "--out", "out"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120,
        stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summaries = {}
    for process in ("umbra", "smart"):
        found = json.loads((tmp_path / "out" / f"summary-{process}.json").read_text())
        summaries.update({m["module"]: m for m in found["modules"]})
    cam, snake = summaries["cam"], summaries["snake"]
    assert cam["fault"] == "remove_patch" and cam["fault_started_at"] is not None
    assert snake["frames"] > 0 and snake["failures"] == 1
