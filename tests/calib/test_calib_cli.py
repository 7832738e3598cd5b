"""``umbra calib fit|zoom|pose|triangulate`` through the CLI's main(argv) and a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from umbra.modules.calib.camcalib import REPORT_FILE
from umbra.modules.calib.rotations import invert_transform, transform, xyz_from_rotation
from umbra.modules.calib.synthetic import (
    observe,
    panel_rig,
    random_pose,
    rig_camera,
    ring_of_cameras,
)
from umbra.modules.calib.zoom_io import load_zoom_table
from umbra.runtime.cli.main import main

REPO = Path(__file__).resolve().parents[2]


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def write_fit_csv(path: Path, noise_px: float = 0.1, seed: int = 41) -> None:
    rng = np.random.default_rng(seed)
    camera = rig_camera()
    points = panel_rig()
    pixels = observe(camera, points, noise_px, rng)
    rows = ["x,y,z,u,v"] + [
        ",".join(f"{v:.9g}" for v in (*p, *uv)) for p, uv in zip(points, pixels, strict=True)
    ]
    path.write_text("# synthetic rig\n" + "\n".join(rows) + "\n")


def test_zoom_json_shape_and_values(capsys) -> None:
    code, out, _ = run(["calib", "zoom", str(REPORT_FILE), "--at", "0.125", "--json"], capsys)
    assert code == 0
    data = json.loads(out)
    assert set(data) == {"zoom", "intrinsics", "extrinsics"}
    assert list(data["intrinsics"]) == ["fx", "fy", "skew", "u0", "v0", "k1", "k2", "p1", "p2"]
    assert list(data["extrinsics"]) == ["dx", "dy", "dz", "rx", "ry", "rz"]
    assert data["intrinsics"]["fx"] == pytest.approx((1004.12 + 1208.51) / 2)
    assert data["extrinsics"]["dz"] == pytest.approx(0.011)


def test_zoom_readable_and_errors(capsys) -> None:
    code, out, _ = run(["calib", "zoom", str(REPORT_FILE), "--at", "0.3"], capsys)
    assert code == 0 and "fx 2314.00" in out and "zcam" in out
    code, _, err = run(["calib", "zoom", str(REPORT_FILE), "--at", "1.5"], capsys)
    assert code == 2 and "0..1" in err and "Traceback" not in err


def test_zoom_malformed_file_exit_2(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text(REPORT_FILE.read_text().replace("<SR_zoom> 0.05", "<SR_zoom> 0.01"))
    code, _, err = run(["calib", "zoom", str(bad), "--at", "0.2"], capsys)
    assert code == 2
    assert f"{bad}:19: error: zoom 0.01 does not increase from the previous zoom 0.025" in err


def test_fit_json_and_written_file(tmp_path: Path, capsys) -> None:
    csv = tmp_path / "pairs.csv"
    write_fit_csv(csv)
    out_file = tmp_path / "cal.xml"
    fit_left = ["calib", "fit", str(csv), "-o", str(out_file), "--camera", "left", "--json"]
    code, out, _ = run([*fit_left, "--zoom", "0.25"], capsys)
    assert code == 0
    data = json.loads(out)
    assert {"rms_px", "intrinsics", "extrinsics", "camera_matrix"} <= set(data)
    truth = rig_camera()
    assert 0.08 < data["rms_px"] < 0.2
    assert data["intrinsics"]["fx"] == pytest.approx(truth.intrinsics.fx, rel=0.01)
    np.testing.assert_allclose(
        [data["extrinsics"][k] for k in ("dx", "dy", "dz")], truth.d, atol=0.01
    )
    np.testing.assert_allclose(
        [data["extrinsics"][k] for k in ("rx", "ry", "rz")],
        xyz_from_rotation(truth.R),
        atol=0.01,
    )
    P = np.array(data["camera_matrix"])
    assert P.shape == (3, 4)
    table = load_zoom_table(out_file)
    assert table.name == "left" and list(table.zooms) == [0.25]
    assert table.intrinsics[0, 0] == pytest.approx(data["intrinsics"]["fx"])
    # A second fit at another zoom is appended, keeping the file sorted by zoom.
    code, _, _ = run([*fit_left, "--zoom", "0.1", "--append"], capsys)
    assert code == 0
    assert list(load_zoom_table(out_file).zooms) == [0.1, 0.25]


def test_fit_readable_and_bad_csv(tmp_path: Path, capsys) -> None:
    csv = tmp_path / "pairs.csv"
    write_fit_csv(csv)
    code, out, _ = run(["calib", "fit", str(csv)], capsys)
    assert code == 0 and "reprojection RMS" in out and "camera matrix" in out
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z,u,v\n0,0,0,1,2\n0,0,1,x,2\n")
    code, _, err = run(["calib", "fit", str(bad)], capsys)
    assert code == 2 and f"{bad}:3: error: bad number 'x' in column u" in err
    header = tmp_path / "header.csv"
    header.write_text("x,y,u,v\n0,0,1,2\n")
    code, _, err = run(["calib", "fit", str(header)], capsys)
    assert code == 2 and f"{header}:1: error: header must name the columns x,y,z,u,v" in err
    planar = tmp_path / "planar.csv"
    planar.write_text(
        "x,y,z,u,v\n" + "\n".join(f"{i % 3},{i // 3},0,{i},{2 * i}" for i in range(9)) + "\n"
    )
    code, _, err = run(["calib", "fit", str(planar)], capsys)
    assert code == 2 and "coplanar" in err and "Traceback" not in err


def cameras_yaml(path: Path, cameras) -> None:
    lines = ["cameras:"]
    for index, camera in enumerate(cameras):
        T_ref_cam = invert_transform(transform(camera.R, camera.d))
        rpy = np.degrees(xyz_from_rotation(T_ref_cam[:3, :3]))
        f = camera.intrinsics
        lines += [
            f"  cam{index}:",
            f"    intrinsics: {{fx: {f.fx}, fy: {f.fy}, skew: {f.skew}, u0: {f.u0}, v0: {f.v0},"
            " k1: -0.1, k2: 0.02}",
            f"    pose: {{xyz: [{', '.join(repr(float(v)) for v in T_ref_cam[:3, 3])}], "
            f"rpy_deg: [{', '.join(repr(float(v)) for v in rpy)}]}}",
        ]
    path.write_text("\n".join(lines) + "\n")


def test_pose_recovers_object_pose(tmp_path: Path, capsys) -> None:
    rng = np.random.default_rng(43)
    cameras = [c.with_distortion([-0.1, 0.02, 0, 0]) for c in ring_of_cameras(3, 2.0)]
    R, d = random_pose(rng)
    rows = ["camera,x,y,z,u,v"]
    for index, camera in enumerate(cameras):
        points = rng.uniform(-0.15, 0.15, (3, 3))
        for p, uv in zip(points, camera.project(points @ R.T + d), strict=True):
            rows.append(f"cam{index}," + ",".join(repr(float(v)) for v in (*p, *uv)))
    (tmp_path / "pairs.csv").write_text("\n".join(rows) + "\n")
    cameras_yaml(tmp_path / "cams.yaml", cameras)
    code, out, err = run(
        [
            "calib",
            "pose",
            str(tmp_path / "pairs.csv"),
            "--cameras",
            str(tmp_path / "cams.yaml"),
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    data = json.loads(out)
    np.testing.assert_allclose(np.array(data["T"]), transform(R, d), atol=1e-7)
    assert data["rms_px"] < 1e-6 and set(data["cameras"]) == {"cam0", "cam1", "cam2"}
    code, out, _ = run(
        ["calib", "pose", str(tmp_path / "pairs.csv"), "--cameras", str(tmp_path / "cams.yaml")],
        capsys,
    )
    assert code == 0 and "rpy_deg" in out
    # Unknown camera name in the CSV.
    (tmp_path / "bad.csv").write_text("camera,x,y,z,u,v\ncam9,0,0,0,1,1\n")
    code, _, err = run(
        ["calib", "pose", str(tmp_path / "bad.csv"), "--cameras", str(tmp_path / "cams.yaml")],
        capsys,
    )
    assert code == 2 and f"{tmp_path / 'bad.csv'}:2: error: unknown camera 'cam9'" in err


def test_triangulate_json(tmp_path: Path, capsys) -> None:
    cameras = [c.with_distortion([-0.1, 0.02, 0, 0]) for c in ring_of_cameras(2, 2.0)]
    cameras_yaml(tmp_path / "cams.yaml", cameras)
    target = np.array([0.05, -0.08, 0.1])
    pixel_args = []
    for index, camera in enumerate(cameras):
        u, v = camera.project(target)
        pixel_args += ["--pixel", f"cam{index}={float(u)!r},{float(v)!r}"]
    code, out, _ = run(
        ["calib", "triangulate", str(tmp_path / "cams.yaml"), *pixel_args, "--json"], capsys
    )
    assert code == 0
    data = json.loads(out)
    np.testing.assert_allclose(data["point"], target, atol=1e-7)
    assert data["gap"] < 1e-7
    code, _, err = run(
        [
            "calib",
            "triangulate",
            str(tmp_path / "cams.yaml"),
            "--pixel",
            "cam0=1;2",
            "--pixel",
            "cam1=3,4",
        ],
        capsys,
    )
    assert code == 2 and "CAMERA=U,V" in err


def test_triangulate_pixel_beyond_the_lens_model(tmp_path: Path, capsys) -> None:
    # k1 = -0.5 folds at a normalized radius of about 0.54: u = 2000 px (1.9) has no preimage.
    intrinsics = "{fx: 900, fy: 900, u0: 320, v0: 240, k1: -0.5}"
    (tmp_path / "cams.yaml").write_text(
        "cameras:\n"
        f"  a: {{intrinsics: {intrinsics}, pose: {{xyz: [0, 0, 0]}}}}\n"
        f"  b: {{intrinsics: {intrinsics}, pose: {{xyz: [0.5, 0, 0]}}}}\n"
    )
    cams = str(tmp_path / "cams.yaml")
    pixels = ["--pixel", "a=330,240", "--pixel", "b=2000,240"]
    code, _, err = run(["calib", "triangulate", cams, *pixels], capsys)
    assert code == 2, err
    assert "a pixel lies outside its camera's distortion model" in err
    assert "Traceback" not in err


def test_cameras_file_from_zoom_file(tmp_path: Path, capsys) -> None:
    (tmp_path / "cams.yaml").write_text(
        "cameras:\n"
        "  a:\n"
        f"    zoom_file: {REPORT_FILE}\n"
        "    zoom: 0.1\n"
        "    mount_pose: {xyz: [-0.3, 0, 0], rpy_deg: [0, 10, 0]}\n"
        "  b:\n"
        f"    zoom_file: {REPORT_FILE}\n"
        "    zoom: 0.1\n"
        "    mount_pose: {xyz: [0.3, 0, 0], rpy_deg: [0, -10, 0]}\n"
    )
    code, out, _ = run(
        [
            "calib",
            "triangulate",
            str(tmp_path / "cams.yaml"),
            "--pixel",
            "a=330,230",
            "--pixel",
            "b=330,230",
            "--json",
        ],
        capsys,
    )
    assert code == 0
    data = json.loads(out)
    # Toed-in by 10 degrees from 0.6 m apart: the axes cross about 1.7 m ahead.
    assert 1.2 < data["point"][2] < 2.2 and min(data["depths"]) > 0
    (tmp_path / "bad.yaml").write_text("cameras:\n  a:\n    zoom: 0.1\n")
    code, _, err = run(
        [
            "calib",
            "triangulate",
            str(tmp_path / "bad.yaml"),
            "--pixel",
            "a=1,2",
            "--pixel",
            "a=1,2",
        ],
        capsys,
    )
    assert code == 2 and f"{tmp_path / 'bad.yaml'}:3: error: camera 'a' needs exactly one" in err


def test_umbra_calib_subprocess() -> None:
    completed = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "calib",
            "zoom",
            str(REPORT_FILE),
            "--at",
            "0.0",
            "--json",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )
    assert completed.returncode == 0, completed.stderr
    assert json.loads(completed.stdout)["intrinsics"]["fx"] == 740.09
    failed = subprocess.run(
        [
            sys.executable,
            "-m",
            "umbra.runtime.cli.main",
            "calib",
            "zoom",
            "missing.xml",
            "--at",
            "0",
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )
    assert failed.returncode == 2
    assert "missing.xml: error: cannot read" in failed.stderr
    assert "Traceback" not in failed.stderr
