"""The 3-D view's pose tool without a browser: click rays on snapshot images and on the model,
the mount correction against the truth, and the saved files solved again by the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from umbra.connectors.messages import CameraModel
from umbra.modules.calib.errors import CalibrationError
from umbra.modules.calib.pose_tool import pose_error
from umbra.modules.geometry.mount_offset import offset_transform
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.geometry import (
    box_mesh,
    frustum_from_model,
    matrix_from_wxyz,
    viewer_pose_looking_at,
)
from umbra.modules.view3d.pose_tool_panel import PoseTool
from umbra.modules.view3d.scene_file import SceneSnapshot
from umbra.runtime.cli.main import main

MODEL = CameraModel(fx=700.0, fy=700.0, u0=320.0, v0=240.0, width=640, height=480)
#: a principal point off the image centre (the page draws the image centred on the frustum)
OFF_CENTRE = CameraModel(fx=820.0, fy=815.0, u0=331.0, v0=244.0, width=640, height=480)
T_TOOL_CAMERA = transform_from_xyz_rpy_deg([0.0, 0.0, -0.12], [0, 0, 0])  # believed mount
ERROR = offset_transform([0.012, -0.02, 0.008], [1.5, -2.0, 2.5])  # true = believed . ERROR
BOX = transform_from_xyz_rpy_deg([0.6, 0.0, 0.35], [0, 0, 20])
BOX_SIZE = np.array([0.3, 0.2, 0.2])
DEPTH = 0.15  # where the test draws each snapshot's image (m)


def features() -> np.ndarray:
    """Points on the box's faces (not on edges), world metres."""
    local = np.array(
        [
            [0.08, 0.05, 0.1],
            [-0.1, -0.06, 0.1],
            [0.12, -0.07, 0.1],
            [-0.05, 0.08, 0.1],
            [0.15, 0.02, -0.05],
            [0.15, -0.06, 0.06],
            [-0.07, -0.1, 0.03],
        ]
    )
    return local @ BOX[:3, :3].T + BOX[:3, 3]


def snapshots(model: CameraModel = MODEL) -> dict:
    """Three snapshots from the tool at different arm poses, posed as the graph believes."""
    out = {}
    for k, (eye, target) in enumerate(
        [
            ([0.75, -0.55, 1.0], [0.6, 0.0, 0.35]),
            ([0.2, -0.45, 0.95], [0.6, 0.0, 0.35]),
            ([1.1, -0.35, 0.8], [0.62, 0.05, 0.3]),
        ]
    ):
        look = viewer_pose_looking_at(eye, target, 0.8)
        T_true = np.eye(4)
        T_true[:3, :3] = matrix_from_wxyz(look.wxyz)
        T_true[:3, 3] = eye
        T_believed = T_true @ np.linalg.inv(ERROR)
        snap = SceneSnapshot(
            f"s{k}", "wrist", T_believed, model.K, np.zeros((480, 640, 3), np.uint8)
        )
        out[snap.id] = (snap, frustum_from_model(model, T_believed), T_true)
    return out


def _seen(T_world_camera: np.ndarray, X: np.ndarray, model: CameraModel = MODEL) -> bool:
    """In front of the camera, inside its image, and on a box face turned towards it."""
    uv = frustum_from_model(model, T_world_camera).pixel_of(X)
    if not (np.all(np.isfinite(uv)) and 0 < uv[0] < 640 and 0 < uv[1] < 480):
        return False
    eye = T_world_camera[:3, 3]
    hit = box_mesh("b", BOX, BOX_SIZE)
    from umbra.modules.view3d.geometry import ray_hit

    first = ray_hit(eye, X - eye, [hit])
    return first is not None and np.linalg.norm(first.point - X) < 1e-9


def click(
    tool: PoseTool, views: dict, snapshot_id: str, X: np.ndarray, model: CameraModel = MODEL
) -> None:
    """The operator clicks X in the image (where the TRUE camera saw it), then on the model."""
    _, frustum, T_true = views[snapshot_id]
    true_frustum = frustum_from_model(model, T_true)
    uv = true_frustum.pixel_of(X)
    on_image = frustum.points_from_pixels(uv[None], DEPTH)[0]
    # the operator looks at this snapshot's image from close by, viewing from that snapshot
    viewer = frustum.T_world_camera[:3, 3] + 0.97 * (on_image - frustum.T_world_camera[:3, 3])
    plain = {k: v[:2] for k, v in views.items()}
    pair = tool.click_image(viewer, on_image - viewer, plain, prefer=snapshot_id)
    assert pair is not None and pair.snapshot_id == snapshot_id
    np.testing.assert_allclose(pair.pixel, uv, atol=1e-9)
    eye = T_true[:3, 3] + np.array([0.0, 0.0, 0.05])  # a viewer near the camera sees X too
    hit = tool.click_model(eye, X - eye, [box_mesh("box", BOX, BOX_SIZE)])
    assert hit is not None and np.linalg.norm(hit - X) < 1e-9


@pytest.mark.parametrize("model", [MODEL, OFF_CENTRE], ids=["centred", "off-centre"])
def test_clicks_solve_the_mount_correction_and_save_for_the_cli(
    model: CameraModel, tmp_path: Path, capsys
) -> None:
    views = snapshots(model)
    tool = PoseTool("tool", "camera", T_TOOL_CAMERA, lambda _id: DEPTH)
    visible = {k: [X for X in features() if _seen(v[2], X, model)] for k, v in views.items()}
    for snapshot_id in views:
        for X in visible[snapshot_id][:4]:
            click(tool, views, snapshot_id, X, model)
    assert len(tool.complete_pairs()) == 12
    plain = {k: v[:2] for k, v in views.items()}
    result = tool.solve(plain)
    angle, offset = pose_error(result.T_parent_child, T_TOOL_CAMERA @ ERROR)
    assert np.degrees(angle) < 1e-4 and offset < 1e-5
    expected_change = pose_error(T_TOOL_CAMERA @ ERROR, T_TOOL_CAMERA)
    np.testing.assert_allclose(tool.change(), (np.degrees(expected_change[0]), expected_change[1]))
    assert result.rms_px < 1e-3
    assert "| s0 |" in tool.residual_table()
    corrected = tool.corrected_mount()
    np.testing.assert_allclose(corrected, T_TOOL_CAMERA @ ERROR, atol=1e-6)
    paths = tool.save(tmp_path, plain)
    assert [p.name for p in paths] == ["mount_tool_camera.yaml", "pose_tool_session.yaml"]
    frames = yaml.safe_load(paths[0].read_text())["frames"]["tool->camera"]
    np.testing.assert_allclose(frames["xyz"], corrected[:3, 3], atol=1e-6)
    # the CLI solves the saved session to the same mount
    assert main(["pose-tool", str(paths[1]), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    angle, offset = pose_error(np.array(data["T"]), corrected)
    assert np.degrees(angle) < 1e-3 and offset < 1e-5


def test_a_click_beside_every_image_or_model_is_ignored() -> None:
    views = snapshots()
    plain = {k: v[:2] for k, v in views.items()}
    tool = PoseTool("tool", "camera", T_TOOL_CAMERA, lambda _id: DEPTH)
    assert tool.click_image([0, 0, 5.0], [0, 0, 1.0], plain) is None  # looking away
    assert tool.click_model([0, 0, 5.0], [0, 0, -1.0], [box_mesh("b", BOX, BOX_SIZE)]) is None
    assert tool.pairs == []


def test_a_click_goes_to_the_viewed_snapshot_where_images_cross() -> None:
    """Snapshots a few degrees apart have images that cross: a click on the image of the
    snapshot viewed from goes to it even where another image is nearer along the ray."""
    views = snapshots()
    snap, frustum, _ = views["s0"]
    twin = SceneSnapshot("s0-again", "wrist", snap.T_world_camera, snap.K, snap.image)
    plain = {"s0": (snap, frustum), "s0-again": (twin, frustum)}
    depths = {"s0": 0.3, "s0-again": 0.15}  # the twin's image is drawn nearer the camera
    tool = PoseTool("tool", "camera", T_TOOL_CAMERA, depths.__getitem__)
    uv = np.array([400.0, 150.0])
    origin = frustum.T_world_camera[:3, 3]
    direction = frustum.points_from_pixels(uv[None], 1.0)[0] - origin
    nearest = tool.click_image(origin, direction, plain)
    assert nearest.snapshot_id == "s0-again"
    viewed = tool.click_image(origin, direction, plain, prefer="s0")
    assert viewed.snapshot_id == "s0"
    np.testing.assert_allclose(viewed.pixel, uv, atol=1e-9)


def test_pairs_from_two_cameras_are_refused() -> None:
    views = snapshots()
    tool = PoseTool("tool", "camera", T_TOOL_CAMERA, lambda _id: DEPTH)
    for snapshot_id in views:
        for X in [X for X in features() if _seen(views[snapshot_id][2], X)][:2]:
            click(tool, views, snapshot_id, X)
    snap, frustum, _ = views["s2"]
    other = SceneSnapshot("s2", "left", snap.T_world_camera, snap.K, snap.image)
    plain = {k: v[:2] for k, v in views.items()} | {"s2": (other, frustum)}
    with pytest.raises(CalibrationError, match="cameras left, wrist"):
        tool.solve(plain)
    assert tool.result is None


def test_a_ptu_base_in_the_static_frames_is_solved_over_ptu_poses(tmp_path: Path, capsys) -> None:
    """The mount in doubt is the PTU's base (``base->ptu``, tied to the world): the camera turns
    with the pan-tilt kinematics between snapshots, so the rays of different snapshots do not
    meet (the non-perspective case); the clicks give the base's true pose, and the saved session
    solves to it again."""
    from umbra.modules.calib.pose_tool_synthetic import T_base_head, nominal_T_head_camera

    T_base_nominal = transform_from_xyz_rpy_deg([0.6, -0.9, 0.7], [0, 0, 90])
    T_base_true = T_base_nominal @ ERROR
    T_head_camera = nominal_T_head_camera()
    views = {}
    for k, (pan, tilt) in enumerate([(0.0, 0.35), (0.12, 0.3), (-0.1, 0.42)]):
        T_chain = T_base_head(pan, tilt) @ T_head_camera
        T_believed = T_base_nominal @ T_chain
        snap = SceneSnapshot(
            f"p{k}", "left", T_believed, OFF_CENTRE.K, np.zeros((480, 640, 3), np.uint8)
        )
        views[snap.id] = (snap, frustum_from_model(OFF_CENTRE, T_believed), T_base_true @ T_chain)
    centres = [v[2][:3, 3] for v in views.values()]
    assert np.linalg.norm(centres[0] - centres[1]) > 0.005  # the camera centre moves
    tool = PoseTool("base", "ptu", T_base_nominal, lambda _id: DEPTH, T_world_parent=np.eye(4))
    for snapshot_id, view in views.items():
        for X in [X for X in features() if _seen(view[2], X, OFF_CENTRE)][:3]:
            click(tool, views, snapshot_id, X, OFF_CENTRE)
    assert len(tool.complete_pairs()) == 9
    plain = {k: v[:2] for k, v in views.items()}
    tool.solve(plain)
    angle, offset = pose_error(tool.corrected_mount(), T_base_true)
    assert np.degrees(angle) < 1e-4 and offset < 1e-5
    assert tool.result.rms_px < 1e-3
    paths = tool.save(tmp_path, plain)
    assert main(["pose-tool", str(paths[1]), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    angle, offset = pose_error(np.array(data["T"]), T_base_true)
    assert np.degrees(angle) < 1e-3 and offset < 1e-5
