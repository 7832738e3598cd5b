"""graphs/zoom_targeting.yaml: two simulated zoom cameras triangulate a marked point while zooming.

SimMarks is checked alone against OpenCV's projection; the graph is checked as `umbra check`
does, run on the real clock (the simulated SONY cameras zoom in wall time), and run once more
from the command line with SimMarks registered by a temporary entry point.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.frames import transform_from_xyz_rpy
from umbra.connectors.messages import CameraModel, Message
from umbra.modules.calib.operator_marks import SimMarks
from umbra.modules.generic.recording import read_recording
from umbra.runtime.graph.check import load_graph
from umbra.runtime.harness import ModuleHarness
from umbra.runtime.registry import Registry
from umbra.runtime.run import run_process
from umbra.runtime.scheduler import SchedulerOptions

ROOT = Path(__file__).resolve().parents[2]
GRAPH = ROOT / "graphs" / "zoom_targeting.yaml"

# -- SimMarks alone -------------------------------------------------------------------------------

T_BASE_MOUNT_A = transform_from_xyz_rpy([-0.2, 0.05, 1.4], list(np.radians([178, -8, 3])))
T_BASE_MOUNT_B = transform_from_xyz_rpy([0.25, -0.02, 1.5], list(np.radians([181, 9, -2])))
FRAMES = {"base->mount_a": T_BASE_MOUNT_A, "base->mount_b": T_BASE_MOUNT_B}
POINT = [0.03, -0.04, 0.05]


def model(mount: str, fx: float, dist: list[float]) -> CameraModel:
    T_mount_camera = transform_from_xyz_rpy([0.004, -0.041, -0.01], [0.02, -0.01, 0.03])
    return CameraModel(
        fx=fx, fy=fx * 1.01, u0=330.0, v0=228.0, dist=np.array(dist),
        T_mount_camera=T_mount_camera, mount=mount, frame=f"{mount}_camera",
    )  # fmt: skip


def opencv_pixel(m: CameraModel, T_base_mount: np.ndarray, point: list[float]) -> np.ndarray:
    T_camera_base = np.linalg.inv(T_base_mount @ m.T_mount_camera)
    rvec, _ = cv2.Rodrigues(T_camera_base[:3, :3])
    K = np.array([[m.fx, 0.0, m.u0], [0.0, m.fy, m.v0], [0.0, 0.0, 1.0]])
    uv, _ = cv2.projectPoints(np.array([point], float), rvec, T_camera_base[:3, 3], K, m.dist)
    return uv.reshape(2)


def test_marks_are_the_opencv_projection_and_poses_the_static_frames() -> None:
    a = model("mount_a", 900.0, [-0.2, 0.1, 0.001, -0.002, 0.0])
    b = model("mount_b", 1500.0, [0.05, 0.0, 0.0, 0.0, 0.0])
    with ModuleHarness(SimMarks, {"point_m": POINT}, frames=FRAMES) as h:
        h.push("camera_a", a)
        assert h.step(0.1) == {}  # one camera model only: nothing to mark yet
        h.push("camera_b", b)
        sent = h.step(0.1)
        np.testing.assert_allclose(
            sent["pixel_a"][0].values, opencv_pixel(a, T_BASE_MOUNT_A, POINT), atol=1e-6
        )
        np.testing.assert_allclose(
            sent["pixel_b"][0].values, opencv_pixel(b, T_BASE_MOUNT_B, POINT), atol=1e-6
        )
        pose_a, pose_b = sent["pose_a"][0], sent["pose_b"][0]
        assert (pose_a.parent, pose_a.child, pose_b.child) == ("base", "mount_a", "mount_b")
        np.testing.assert_allclose(pose_a.matrix, T_BASE_MOUNT_A)
        np.testing.assert_allclose(pose_b.matrix, T_BASE_MOUNT_B)
        np.testing.assert_allclose(sent["truth"][0].values, POINT)


def test_click_noise_has_the_asked_spread() -> None:
    a, b = model("mount_a", 900.0, [0.0] * 5), model("mount_b", 900.0, [0.0] * 5)
    exact = opencv_pixel(a, T_BASE_MOUNT_A, POINT)
    with ModuleHarness(
        SimMarks, {"point_m": POINT, "click_noise_px": 0.5}, frames=FRAMES, seed=4
    ) as h:
        h.push("camera_a", a)
        h.push("camera_b", b)
        h.run(400, 0.01)
        clicks = np.array([s.values for s in h.outputs("pixel_a")])
    assert len(clicks) == 400
    errors = clicks - exact
    np.testing.assert_allclose(errors.std(axis=0), [0.5, 0.5], rtol=0.15)
    np.testing.assert_allclose(errors.mean(axis=0), [0.0, 0.0], atol=0.1)


def test_no_marks_when_the_point_is_out_of_view() -> None:
    a, b = model("mount_a", 900.0, [0.0] * 5), model("mount_b", 900.0, [0.0] * 5)
    behind = [0.0, 0.0, 3.0]  # above the cameras, which look down
    aside = [1.5, 0.0, 0.0]  # in front of them, but far off the image
    for point in (behind, aside):
        with ModuleHarness(SimMarks, {"point_m": point}, frames=FRAMES) as h:
            h.push("camera_a", a)
            h.push("camera_b", b)
            sent = h.step(0.1)
            assert "pixel_a" not in sent and "pixel_b" not in sent
            assert h.module.summary() == {"marks": 0, "out_of_view": 1}


def test_a_mount_without_static_frame_is_a_user_error() -> None:
    with ModuleHarness(SimMarks, {}, frames=FRAMES) as h:
        h.push("camera_a", model("mount_a", 900.0, [0.0] * 5))
        h.push("camera_b", model("ptu_left", 900.0, [0.0] * 5))
        with pytest.raises(UserError, match="base->ptu_left"):
            h.step(0.1)


# -- the graph ------------------------------------------------------------------------------------


def registry() -> Registry:
    reg = Registry()
    reg.add(SimMarks)
    return reg


def recording(path: Path) -> dict[str, list[Message]]:
    channels: dict[str, list[Message]] = {}
    for channel, sample in read_recording(path):
        channels.setdefault(channel, []).append(sample)
    return channels


def zoom_at(zooms: list[Message], stamps: np.ndarray) -> np.ndarray:
    """The latest reported zoom at each stamp (the zoom the camera models were made from)."""
    t = np.array([z.stamp for z in zooms])
    z = np.array([z.zoom for z in zooms])
    index = np.searchsorted(t, stamps, side="right") - 1
    return np.where(index >= 0, z[np.maximum(index, 0)], np.nan)


def test_graph_checks_like_umbra_check() -> None:
    plan = load_graph(str(GRAPH), registry())
    assert plan.spec.clock == "real"
    types = {name: m.spec.type for name, m in plan.modules.items()}
    assert sorted(types.values()).count("SONY") == 2 and types["marks"] == "SimMarks"
    # the stereo head: 0.3 m baseline, both optical axes through the marked point
    T_left, T_right = (
        plan.frames.lookup("base", "cam_left"),
        plan.frames.lookup("base", "cam_right"),
    )
    assert np.linalg.norm(T_left[:3, 3] - T_right[:3, 3]) == pytest.approx(0.3)
    point = np.array(plan.modules["marks"].params.point_m)
    for T in (T_left, T_right):
        to_point = point - T[:3, 3]
        assert np.degrees(np.arccos(T[:3, 2] @ to_point / np.linalg.norm(to_point))) < 0.1


def test_targeting_holds_while_the_operator_zooms(tmp_path: Path) -> None:
    plan = load_graph(str(GRAPH), registry())
    noise_px = plan.modules["marks"].params.click_noise_px
    assert noise_px > 0
    result = run_process(plan, SchedulerOptions(clock="real", duration=4.5, output_dir=tmp_path))
    assert result.exit_code == 0, result.reason
    rec = recording(tmp_path / "targets.mcap")
    truth = rec["truth"][0].values
    points = np.array([s.values for s in rec["point"]])
    stamps = np.array([s.stamp for s in rec["point"]])
    gaps = np.array([s.value for s in rec["gap"]])
    assert len(points) >= 20
    # the zoom really changed under the targeting: points at wide and at tele zooms
    for side in ("zoom_left", "zoom_right"):
        zooms = zoom_at(rec[side], stamps)
        assert np.nanmin(zooms) < 0.05 and np.nanmax(zooms) > 0.25, side
        assert len(np.unique(zooms[np.isfinite(zooms)])) >= 10, side
    # within a few mm of the true point (0.2 px clicks at 1.5 m over a 0.3 m baseline)
    errors = np.linalg.norm(points - truth, axis=1)
    assert np.sqrt(np.mean(errors**2)) < 0.004
    assert errors.max() < 0.015
    assert gaps.max() < 0.003
    assert {s.stage for s in rec["status"]} == {"ok"}
    # the rendered images show the patch where the operator clicked (same tick, same model)
    for seen_side, click_side in (("seen_left", "click_left"), ("seen_right", "click_right")):
        clicks = {c.stamp: c.values for c in rec[click_side]}
        matched = [(s.centroid, clicks[s.stamp]) for s in rec[seen_side] if s.stamp in clicks]
        assert len(matched) >= 10 and all(s.status == "tracking" for s in rec[seen_side])
        offsets = np.array([np.linalg.norm(c - uv) for c, uv in matched])
        assert offsets.max() < 5 * noise_px + 0.5


def test_umbra_run_from_the_command_line(tmp_path: Path) -> None:
    """With SimMarks registered by an entry point (as pyproject will), and exact clicks."""
    site = tmp_path / "site"
    dist = site / "umbra_simmarks-0.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: umbra-simmarks\nVersion: 0.0\n")
    (dist / "entry_points.txt").write_text(
        "[umbra.modules]\nSimMarks = umbra.modules.calib.operator_marks:SimMarks\n"
    )
    env = {**os.environ, "PYTHONPATH": f"{site}{os.pathsep}{ROOT}"}
    out = tmp_path / "run"
    command = [sys.executable, "-m", "umbra.runtime.cli.main"]
    check = subprocess.run(
        [*command, "check", str(GRAPH)], capture_output=True, text=True, env=env, timeout=60
    )
    assert check.returncode == 0, check.stderr
    proc = subprocess.run(
        # the graph's whole 6 s: the zoom motors run on the wall clock, and beside busy loops
        # 2.5 s saw zooms of 0 .. 0.10 only
        [*command, "run", str(GRAPH), "--out", str(out),
         "--set", "marks.click_noise_px=0", "--quiet"],
        capture_output=True, text=True, env=env, timeout=60, cwd=tmp_path,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    rec = recording(out / "targets.mcap")
    points = np.array([s.values for s in rec["point"]])
    stamps = np.array([s.stamp for s in rec["point"]])
    zooms = zoom_at(rec["zoom_left"], stamps)
    assert np.nanmax(zooms) - np.nanmin(zooms) > 0.2
    # exact clicks: the rays meet at the true point whatever the zoom
    np.testing.assert_allclose(points, [rec["truth"][0].values] * len(points), atol=1e-6)
    assert max(s.value for s in rec["gap"]) < 1e-6
