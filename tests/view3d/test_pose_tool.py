"""The camera-pose tool: the mount solved against the truth, session files, ``umbra pose-tool``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from umbra.modules.calib.camera_model import PinholeCamera
from umbra.modules.calib.errors import DegenerateGeometryError
from umbra.modules.calib.pose_tool import MountSnapshot, pose_error, solve_mount
from umbra.modules.calib.pose_tool_file import parse_session, session_text, update_graph_frame
from umbra.modules.calib.pose_tool_synthetic import (
    PTU_INTRINSICS,
    T_WORLD_PTU_BASE,
    T_base_head,
    click_snapshots,
    nominal_T_head_camera,
    random_case,
    table_points,
)
from umbra.modules.geometry.mount_offset import offset_mount, offset_transform
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg, xyz_rpy_deg_from_transform
from umbra.runtime.cli.main import main

REPO = Path(__file__).resolve().parents[2]


def test_head_mount_recovered_exactly_without_noise() -> None:
    rng = np.random.default_rng(3)
    case = random_case(rng, snapshots=3, points=6)
    snapshots = click_snapshots(case, 0.0, rng)
    before = pose_error(case.T_head_camera_nominal, case.T_head_camera_true)
    assert before[0] > np.radians(0.3) or before[1] > 0.005  # there is an error to find
    result = solve_mount(snapshots, case.T_head_camera_nominal)
    angle, offset = pose_error(result.T_parent_child, case.T_head_camera_true)
    assert angle < 1e-8 and offset < 1e-9
    assert result.rms_px < 1e-6
    # residuals at the believed mount are reported, and are large (pixels)
    assert max(np.abs(r).max() for r in result.initial_residuals) > 5.0


def test_several_ptu_poses_beat_one_snapshot_with_noise() -> None:
    rng = np.random.default_rng(11)
    multi, single = [], []
    for _ in range(25):
        case = random_case(rng, snapshots=3, points=6)
        snapshots = click_snapshots(case, 1.0, rng)
        r = solve_mount(snapshots, case.T_head_camera_nominal)
        multi.append(pose_error(r.T_parent_child, case.T_head_camera_true))
        r1 = solve_mount(snapshots[:1], case.T_head_camera_nominal)
        single.append(pose_error(r1.T_parent_child, case.T_head_camera_true))
    multi_a, multi_t = np.median(np.array(multi), axis=0)
    single_a, single_t = np.median(np.array(single), axis=0)
    assert np.degrees(multi_a) < 0.2 and multi_t < 0.003
    assert multi_a < single_a and multi_t < single_t


def test_ptu_base_in_world_non_perspective() -> None:
    """Unknown PTU base pose, camera mount known: rays of different snapshots do not meet."""
    T_true = offset_mount(T_WORLD_PTU_BASE, offset_transform([0.02, -0.03, 0.01], [2.0, -1.5, 3.0]))
    camera = PinholeCamera(PTU_INTRINSICS)
    T_head_camera = nominal_T_head_camera()
    snapshots = []
    for pan, tilt in [(-0.05, 0.2), (0.1, 0.3), (0.02, 0.35)]:
        T_child_camera = T_base_head(pan, tilt) @ T_head_camera
        seen = camera.with_extrinsic_matrix(np.linalg.inv(T_true @ T_child_camera))
        pixels = seen.project(table_points())
        inside = np.all((pixels > 0) & (pixels < [640, 480]), axis=1)
        assert inside.sum() >= 2
        snapshots.append(
            MountSnapshot(camera, table_points()[inside], pixels[inside], np.eye(4), T_child_camera)
        )
    # the camera centre moves between snapshots (it is off the pan and tilt axes)
    centres = [s.T_world_camera(T_true)[:3, 3] for s in snapshots]
    assert np.linalg.norm(centres[0] - centres[1]) > 0.005
    result = solve_mount(snapshots, T_WORLD_PTU_BASE)
    angle, offset = pose_error(result.T_parent_child, T_true)
    assert angle < 1e-8 and offset < 1e-9


def test_too_few_clicks_is_refused() -> None:
    camera = PinholeCamera(PTU_INTRINSICS)
    snap = MountSnapshot(camera, table_points()[:2], np.array([[100.0, 100.0], [200.0, 120.0]]))
    with pytest.raises(DegenerateGeometryError, match="at least 3"):
        solve_mount([snap])


def test_mount_offset_module_moves_the_pose_in_its_own_axes() -> None:
    from umbra.connectors.messages import Pose
    from umbra.modules.vision.mount_offset_module import MountOffset
    from umbra.runtime.harness import ModuleHarness

    T = transform_from_xyz_rpy_deg([0.3, 0.0, 0.5], [180.0, 0.0, 0.0])
    with ModuleHarness(MountOffset, {"xyz_m": [0.0, 0.0, 0.02], "rpy_deg": [0, 3.0, 0]}) as h:
        h.push("pose", Pose(matrix=T, parent="table", child="camera", stamp=1.5))
        h.step(dt=0.01)
        out = h.output("offset_pose")
    assert (out.parent, out.child, out.stamp) == ("table", "camera", 1.5)
    np.testing.assert_allclose(out.matrix[:3, 3], [0.3, 0.0, 0.48], atol=1e-12)  # z flipped
    angle, _ = pose_error(out.matrix, T)
    assert np.degrees(angle) == pytest.approx(3.0)


def test_mount_offset_is_in_the_child_axes() -> None:
    T = transform_from_xyz_rpy_deg([1.0, 2.0, 3.0], [0.0, 0.0, 90.0])
    moved = offset_mount(T, offset_transform([0.1, 0.0, 0.0], [0.0, 0.0, 0.0]))
    np.testing.assert_allclose(moved[:3, 3], [1.0, 2.1, 3.0], atol=1e-12)  # child x = parent y
    with pytest.raises(ValueError, match="finite"):
        offset_transform([np.nan, 0, 0], [0, 0, 0])


def _session(rng: np.random.Generator, noise: float = 0.5) -> tuple[str, np.ndarray]:
    case = random_case(rng, snapshots=3, points=6)
    snapshots = click_snapshots(case, noise, rng)
    names = {tuple(p): f"p{i}" for i, p in enumerate(table_points())}
    points = {f"p{i}": p for i, p in enumerate(table_points())}
    entries = []
    for s in snapshots:
        clicks = {
            names[tuple(p)]: tuple(uv) for p, uv in zip(s.points_world, s.pixels, strict=True)
        }
        entries.append((s.T_world_parent, s.T_child_camera, clicks))
    text = session_text(
        "ptu_head", "camera", snapshots[0].camera, points, entries, case.T_head_camera_nominal
    )
    return text, case.T_head_camera_true


def test_session_file_round_trip_solves_the_same() -> None:
    text, truth = _session(np.random.default_rng(8), noise=0.0)
    session = parse_session(text, "s.yaml")
    assert (session.parent, session.child) == ("ptu_head", "camera")
    result = solve_mount(session.snapshots, session.initial)
    angle, offset = pose_error(result.T_parent_child, truth)
    # the file rounds pixels to 1e-3 px and poses to 1e-6 m / 1e-5 deg
    assert np.degrees(angle) < 0.002 and offset < 3e-5


@pytest.mark.parametrize(
    ("edit", "line", "message"),
    [
        (
            lambda t: t.replace("mount: ptu_head->camera", "mount: ptu_head camera"),
            2,
            "parent->child",
        ),
        (lambda t: t.replace("clicks: {p", "clicks: {nowhere: [1, 2], p", 1), 0, "unknown point"),
        (lambda t: t.replace("fx: 820", "fx: -820"), 4, "positive"),
        (lambda t: t.replace("  p0: [", "  p0: [nan, 0, 0]  # "), 6, "finite"),
        (lambda t: t.replace("  p0: [", "  p0: [0, "), 6, "3 numbers"),
        (lambda t: t.replace("points:", "pointz:"), 0, "unknown key"),
    ],
)
def test_bad_session_files_name_the_line(edit, line, message, tmp_path: Path, capsys) -> None:
    text, _ = _session(np.random.default_rng(8))
    bad = edit(text)
    path = tmp_path / "bad.yaml"
    path.write_text(bad)
    code = main(["pose-tool", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and message in err and "Traceback" not in err
    if line:
        assert f"bad.yaml:{line}: error:" in err
    else:
        assert "bad.yaml:" in err and ": error:" in err


def test_cli_solves_and_writes_frames_and_graph(tmp_path: Path, capsys) -> None:
    text, truth = _session(np.random.default_rng(21), noise=0.5)
    session = tmp_path / "session.yaml"
    session.write_text(text)
    graph = tmp_path / "g.yaml"
    graph.write_text(
        "graph: g  # keep me\nframes:\n  base->ptu_head: {xyz: [0, 0, 1]}\n"
        "  ptu_head->camera: {xyz: [0.03, 0, 0.05], rpy_deg: [-90, 0, -90]}  # nominal\n"
        "modules: {}\n"
    )
    out = tmp_path / "mount.yaml"
    code = main(["pose-tool", str(session), "--json", "-o", str(out), "--graph", str(graph)])
    data = json.loads(capsys.readouterr().out)
    assert code == 0
    angle, offset = pose_error(np.array(data["T"]), truth)
    assert np.degrees(angle) < 0.3 and offset < 0.005
    assert data["rms_px"] < 1.5 and len(data["clicks"]) >= 9
    assert all(c["before_px"] > c["residual_px"] for c in data["clicks"][:1])
    # the mount's stated errors: the 95 % intervals hold the truth's offset, a few mm wide
    half = data["interval_95"]
    assert set(half) == {"rx", "ry", "rz", "x", "y", "z"} and len(data["covariance"]) == 6
    assert np.all(
        np.abs(np.array(data["T"])[:3, 3] - truth[:3, 3])
        < 3 * np.array([half["x"], half["y"], half["z"]])
    )
    assert all(1e-4 < half[k] < 0.02 for k in ("x", "y", "z")), half
    xyz, rpy = xyz_rpy_deg_from_transform(np.array(data["T"]))
    new_graph = graph.read_text()
    assert "graph: g  # keep me" in new_graph and "# nominal" in new_graph
    assert f"{xyz[0]:.6f}" in new_graph and f"{rpy[2]:.5f}" in new_graph
    assert "ptu_head->camera" in out.read_text()
    # the written graph frame parses back to the solved mount
    session_from_graph = parse_session(
        text.replace(
            text.split("\n")[2],
            "initial: " + new_graph.split("ptu_head->camera: ")[1].split("  #")[0],
        )
    )
    np.testing.assert_allclose(session_from_graph.initial, np.array(data["T"]), atol=1e-5)


def test_update_graph_frame_adds_a_missing_entry() -> None:
    text = "graph: g\nframes:\n  a->b: {xyz: [0, 0, 0]}\nmodules: {}\n"
    out = update_graph_frame(text, "x", "y", np.eye(4), "g.yaml")
    assert "  x->y: {xyz: [0.000000, 0.000000, 0.000000]" in out and "a->b" in out


@pytest.mark.slow
@pytest.mark.untimed
def test_cli_subprocess_bad_file_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "s.yaml"
    path.write_text("mount: a->b\ncamera: {fx: 800, fy: 800, u0: 320, v0: 240}\npoints: {}\n")
    done = subprocess.run(
        [sys.executable, "-m", "umbra.runtime.cli.main", "pose-tool", str(path)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )
    assert done.returncode == 2, done.stderr
    assert "s.yaml:" in done.stderr and "Traceback" not in done.stderr
