"""``umbra pose-tool``'s inputs: non-finite options, clicks that cannot determine a mount, and
mount names a graph would refuse are each a located error with exit status 2, before anything is
solved or written (issue #29: ``--max-rms-px nan`` turned the accuracy guard off, six clicks on one
point "solved" at 0.000 px, and a mount name went unchecked into ``--graph``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from umbra.modules.calib.camera_model import Intrinsics, PinholeCamera
from umbra.modules.calib.pose_tool_file import session_text
from umbra.modules.calib.pose_tool_synthetic import (
    click_snapshots,
    random_case,
    table_points,
)
from umbra.runtime.cli.main import main

GRAPH = """graph: g  # keep me
frames:
  base->ptu_head: {xyz: [0, 0, 1]}
modules:
  src: {type: TwistSource, rate: 10}
"""


def _valid_session(parent: str = "ptu_head", child: str = "camera") -> str:
    rng = np.random.default_rng(21)
    case = random_case(rng, snapshots=3, points=6)
    snapshots = click_snapshots(case, 0.5, rng)
    names = {tuple(p): f"p{i}" for i, p in enumerate(table_points())}
    points = {f"p{i}": p for i, p in enumerate(table_points())}
    entries = [
        (
            s.T_world_parent,
            s.T_child_camera,
            {names[tuple(p)]: tuple(uv) for p, uv in zip(s.points_world, s.pixels, strict=True)},
        )
        for s in snapshots
    ]
    return session_text(parent, child, snapshots[0].camera, points, entries)


CAMERA = PinholeCamera(Intrinsics(800.0, 800.0, 0.0, 320.0, 240.0))


def _clicks_session(points: dict[str, list[float]], snapshots: list[dict]) -> str:
    """A hand-made session: the parent at the world origin in every snapshot."""
    entries = [(np.eye(4), np.eye(4), clicks) for clicks in snapshots]
    return session_text(
        "ptu_head", "camera", CAMERA, {k: np.array(v) for k, v in points.items()}, entries
    )


def _run(tmp_path: Path, text: str, *options: str, capsys) -> tuple[int, str]:
    session = tmp_path / "session.yaml"
    session.write_text(text)
    code = main(["pose-tool", str(session), *options])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "0", "-1"])
def test_max_rms_must_be_a_finite_positive_number(value: str, tmp_path: Path, capsys) -> None:
    out = tmp_path / "mount.yaml"
    code, err = _run(
        tmp_path, _valid_session(), f"--max-rms-px={value}", "-o", str(out), capsys=capsys
    )
    assert code == 2
    assert "--max-rms-px: expected a finite number of pixels > 0, found" in err
    assert not out.exists()


def test_a_valid_session_still_solves_and_saves(tmp_path: Path, capsys) -> None:
    out = tmp_path / "mount.yaml"
    code, err = _run(tmp_path, _valid_session(), "--max-rms-px", "5", "-o", str(out), capsys=capsys)
    assert code == 0, err
    assert "ptu_head->camera" in out.read_text()


def test_six_clicks_on_one_point_are_refused(tmp_path: Path, capsys) -> None:
    """Six snapshots from one parent pose, each clicking the same point: a mount that fits every
    click exactly (0 px) exists in every direction; the file is refused saying so."""
    text = _clicks_session({"a": [0.0, 0.0, 0.5]}, [{"a": (320.0, 240.0)}] * 6)
    code, err = _run(tmp_path, text, capsys=capsys)
    assert code == 2
    assert "error: all 6 clicks are on one point (seen from the mount's parent frame)" in err


def test_six_names_for_one_place_are_one_point(tmp_path: Path, capsys) -> None:
    points = {f"p{i}": [0.1, 0.2, 0.5] for i in range(6)}
    text = _clicks_session(points, [{f"p{i}": (400.0 + i, 300.0) for i in range(6)}])
    code, err = _run(tmp_path, text, capsys=capsys)
    assert code == 2 and "all 6 clicks are on one point" in err


def test_collinear_points_are_refused(tmp_path: Path, capsys) -> None:
    points = {f"p{i}": [0.05 * i, 0.02 * i, 0.5 + 0.01 * i] for i in range(5)}
    clicks = {f"p{i}": (320.0 + 80 * 0.05 * i / (0.5 + 0.01 * i), 240.0) for i in range(5)}
    code, err = _run(tmp_path, _clicks_session(points, [clicks]), capsys=capsys)
    assert code == 2
    assert "error: the 5 clicked points lie on one line (seen from the mount's parent frame)" in err


def test_one_point_seen_from_several_parent_poses_is_not_one_point(tmp_path: Path) -> None:
    """The same world point from parent poses that differ is several points in the parent frame
    (as a PTU head sees one target while it turns): not refused as degenerate."""
    from umbra.modules.calib.pose_tool_file import parse_session
    from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg

    poses = [transform_from_xyz_rpy_deg([0, 0, 0], [0, p, y]) for p, y in [(0, 0), (5, 0), (0, 5)]]
    text = session_text(
        "ptu_head",
        "camera",
        CAMERA,
        {"a": np.array([0.0, 0.0, 0.5]), "b": np.array([0.1, 0.0, 0.5])},
        [(T, np.eye(4), {"a": (320.0, 240.0), "b": (480.0, 240.0)}) for T in poses],
    )
    assert len(parse_session(text, "s.yaml").snapshots) == 3


@pytest.mark.parametrize(
    ("mount", "why"),
    [
        ("'&a x->camera'", "frame name '&a x' must be an identifier"),
        ("ptu head->camera", "frame name 'ptu head' must be an identifier"),
        ("ptu_head->cam:era", "frame name 'cam:era' must be an identifier"),
        ("1head->camera", "frame name '1head' must be an identifier"),
        ("a->b->c", "frame name 'b->c' must be an identifier"),
        ("camera->camera", "names one frame twice"),
    ],
)
def test_mount_names_a_graph_refuses_are_refused_before_anything_is_written(
    mount: str, why: str, tmp_path: Path, capsys
) -> None:
    text = _valid_session().replace("mount: ptu_head->camera", f"mount: {mount}")
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH)
    out = tmp_path / "mount.yaml"
    code, err = _run(tmp_path, text, "--graph", str(graph), "-o", str(out), capsys=capsys)
    assert code == 2
    assert "session.yaml:2: error: mount" in err and why in err, err
    assert graph.read_text() == GRAPH and not out.exists()


def test_what_graph_writes_passes_check(tmp_path: Path, capsys) -> None:
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH)
    assert main(["check", str(graph)]) == 0
    code, err = _run(tmp_path, _valid_session(), "--graph", str(graph), capsys=capsys)
    assert code == 0, err
    assert "ptu_head->camera: {xyz: [" in graph.read_text()
    assert main(["check", str(graph)]) == 0, capsys.readouterr()


@pytest.mark.parametrize("writer", ["session_text", "frames_text", "update_graph_frame"])
def test_no_writer_writes_a_name_a_graph_refuses(writer: str) -> None:
    """The 3-D view's pose tool writes through the same functions: a bad name is refused there."""
    from umbra.modules.calib import pose_tool_file as f

    calls = {
        "session_text": lambda: f.session_text("&a x", "camera", CAMERA, {}, []),
        "frames_text": lambda: f.frames_text("ptu_head", "cam era", np.eye(4), "c"),
        "update_graph_frame": lambda: f.update_graph_frame(GRAPH, "a->b", "c", np.eye(4), "g"),
    }
    with pytest.raises(ValueError, match="must be an identifier"):
        calls[writer]()
