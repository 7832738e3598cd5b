"""The simulated cameras draw the arm where its true frames put it: the wrist camera its
fingers (DigiCam, ``arm_poses``), the Active Sketch cameras the links too (SketchCam's
renderer); nothing when the arm is out of view."""

from __future__ import annotations

import cv2
import numpy as np

from umbra.connectors.messages import CameraModel, Pose, Poses
from umbra.modules.arm.arm_params import ArmParams
from umbra.modules.arm.arm_solids import FINGERS, arm_boxes, arm_frames, box_corners, finger_offsets
from umbra.modules.vision.arm_view import arm_in, with_arm
from umbra.modules.vision.digicam import DigiCam
from umbra.modules.vision.scene import camera_looking_down
from umbra.modules.vision.sketch_render import render_scene
from umbra.modules.world.scene_objects import SketchScene
from umbra.runtime.harness import ModuleHarness

#: the shipped pick-up's 720p wrist camera (graphs/tool_pickup.yaml)
W, H = 1280, 720
K = np.array([[800.0, 0.0, 640.0], [0.0, 800.0, 360.0], [0.0, 0.0, 1.0]])
#: the wrist camera 0.22 m above the patch, looking down; the tool point 0.12 m in front of it
T_WORLD_CAMERA = camera_looking_down((0.0, 0.0, 0.03), 0.22)
T_CAMERA_TOOL = np.eye(4)
T_CAMERA_TOOL[2, 3] = 0.12


def _fingers(T_world_tool: np.ndarray, opening: float = 1.0) -> Poses:
    """The tool and finger frames (as World publishes them) for a tool at ``T_world_tool``."""
    matrices = [T_world_tool]
    for offset in finger_offsets(opening):
        T = T_world_tool.copy()
        T[:3, 3] = T_world_tool[:3, :3] @ offset + T_world_tool[:3, 3]
        matrices.append(T)
    return Poses(matrices=np.stack(matrices), children=("tool", *FINGERS), frame="world")


def _projected_area(poses: Poses) -> tuple[np.ndarray, int]:
    """A mask of the pixels the finger boxes cover (their projected convex hulls) and its area."""
    mask = np.zeros((H, W), np.uint8)
    T_camera_world = np.linalg.inv(T_WORLD_CAMERA)
    for T, size in arm_boxes(poses.matrices, tuple(poses.children)):
        corners = box_corners(T, size) @ T_camera_world[:3, :3].T + T_camera_world[:3, 3]
        uv = corners[:, :2] / corners[:, 2:3] @ K[:2, :2].T + K[:2, 2]
        hull = cv2.convexHull(np.round(uv * 16).astype(np.int32))
        cv2.fillConvexPoly(mask, hull, 1, cv2.LINE_8, 4)
    return mask, int(mask.sum())


def _frames(arm: Poses | None) -> tuple[np.ndarray, object]:
    model = CameraModel(fx=800.0, fy=800.0, u0=640.0, v0=360.0, width=W, height=H)
    with ModuleHarness(DigiCam, {"background": "flat", "noise_sigma": 0.0}) as h:
        h.push("camera_model", model)
        h.push("camera_pose", Pose(matrix=T_WORLD_CAMERA, parent="world", child="camera"))
        if arm is not None:
            h.push("arm_poses", arm)
        out = h.step(0.1)
    return out["image"][0].pixels, out["truth"][0]


def test_the_wrist_camera_draws_the_fingers_where_they_project() -> None:
    arm = _fingers(T_WORLD_CAMERA @ T_CAMERA_TOOL)
    bare, bare_truth = _frames(None)
    drawn, truth = _frames(arm)
    changed = np.any(drawn.astype(int) != bare, axis=2)
    mask, area = _projected_area(arm)
    assert area > 3000  # two fingers open wide: short strips at the top and bottom borders
    # the changed pixels are the projected fingers: overlap (IoU) within the edges' half pixel
    inter = np.count_nonzero(changed & (mask > 0))
    union = np.count_nonzero(changed | (mask > 0))
    assert inter / union > 0.95, (inter, union, area)
    rows = np.nonzero(changed.any(axis=1))[0]
    assert rows.min() == 0 and rows.max() == H - 1  # from each border inwards
    assert np.all((rows < 40) | (rows > H - 40))  # a strip at the border, the patch far from it
    # dark grey fingers over the brown table
    assert drawn[changed].mean() < 75 and bare[changed].mean() > 80
    # the patch is untouched, and so is its ground truth
    np.testing.assert_allclose(truth.vertices, bare_truth.vertices)
    assert truth.reason == bare_truth.reason == "100% of the patch visible"


def test_closing_fingers_move_inwards() -> None:
    tool = T_WORLD_CAMERA @ T_CAMERA_TOOL
    open_mask, _ = _projected_area(_fingers(tool, 1.0))
    half_mask, _ = _projected_area(_fingers(tool, 0.3))
    half, _ = _frames(_fingers(tool, 0.3))
    bare, _ = _frames(None)
    changed = np.any(half.astype(int) != bare, axis=2)
    assert np.count_nonzero(changed & (half_mask > 0)) / max(np.count_nonzero(changed), 1) > 0.95
    assert not half_mask[360, 640] and not changed[360, 640]  # a gap between the fingers

    def edges(mask: np.ndarray) -> tuple[int, int]:
        """Inner edges of the top and bottom fingers on the centre column (rows)."""
        rows = np.nonzero(mask[:, 640])[0]
        return int(rows[rows < 360].max()), int(rows[rows > 360].min())

    (top_open, bottom_open), (top_half, bottom_half) = edges(open_mask), edges(half_mask)
    assert top_half > top_open + 20 and bottom_half < bottom_open - 20  # nearer the middle


def test_no_arm_pixels_when_the_arm_is_out_of_view() -> None:
    away = np.eye(4)
    away[:3, 3] = [1.5, 0.0, 0.5]  # the arm's tool 1.5 m aside, beyond the field of view
    behind = T_WORLD_CAMERA.copy()
    behind[2, 3] += 0.3  # the tool above the camera, behind its lens
    assert _projected_area(_fingers(away))[1] == 0  # the projection misses the image
    bare, _ = _frames(None)
    for T in (away, behind):
        drawn, _ = _frames(_fingers(T))
        np.testing.assert_array_equal(drawn, bare)


def test_the_sketch_cameras_draw_the_links_where_they_project() -> None:
    table = ArmParams().table
    q = np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0])
    T_flange_tool = np.eye(4)
    T_flange_tool[2, 3] = 0.14
    matrices, children = arm_frames(table, q, T_flange_tool, 1.0)
    arm = Poses(matrices=matrices, children=children, frame="base")
    objects = SketchScene.nominal().message()
    eye, target = np.array([-0.6, 0.5, 1.2]), np.array([0.45, 0.0, 0.35])
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T_base_camera = np.eye(4)
    T_base_camera[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T_base_camera[:3, 3] = eye
    boxes = arm_in(arm, np.eye(4))
    K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
    bare = render_scene(objects, K, T_base_camera, 640, 480)
    drawn = render_scene(with_arm(objects, boxes), K, T_base_camera, 640, 480)
    T_camera_base = np.linalg.inv(T_base_camera)
    seen = 0
    for T, _, _ in boxes:
        c = T_camera_base[:3, :3] @ T[:3, 3] + T_camera_base[:3, 3]
        u, v = (K[:2, :2] @ (c[:2] / c[2]) + K[:2, 2]).round().astype(int)
        if 0 <= u < 640 and 0 <= v < 480:
            seen += 1
            assert np.any(drawn[v, u] != bare[v, u]), (u, v)  # the box's centre is arm
    assert seen >= 3  # the forearm, the wrist and a finger at least
    # looking away from the arm: the same image with and without it
    T_away = T_base_camera @ np.diag([-1.0, 1.0, -1.0, 1.0])  # turned half round about y
    np.testing.assert_array_equal(
        render_scene(with_arm(objects, boxes), K, T_away, 640, 480),
        render_scene(objects, K, T_away, 640, 480),
    )
