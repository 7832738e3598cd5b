"""The camera-pose tool end to end in a real browser (Debian's Chromium through Playwright).

A camera on a pan-tilt unit is bolted on a few degrees and centimetres off its nominal mount
(the graph believes the nominal one; the images come from the true one). In the page: three
snapshots at three PTU poses ("Snapshot left"), then for each snapshot "View from snapshot", a
mouse click on a feature in the snapshot's image and a click on the same feature in the model
(the ray hits the surface), "Solve mount" (nPnP over every pair), the residual table in the
page, "Save mount": the saved mount is the true one, within the clicks' precision.
"""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import cv2
import msgspec
import numpy as np
import pytest
import yaml

from tests.poll import wait_for
from tests.view3d.browser_support import (
    block_outside_loopback,
    canvas_box,
    needs_chromium,
    project_to_page,
)
from tests.view3d.view_page import first_client
from umbra.connectors.messages import CameraModel, Image, Pose
from umbra.connectors.scene_messages import SceneObjects
from umbra.modules.calib.pose_tool import pose_error
from umbra.modules.calib.pose_tool_synthetic import T_WORLD_PTU_BASE, T_base_head, aim
from umbra.modules.geometry.mount_offset import offset_transform
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.geometry import (
    frustum_from_model,
    ray_hit,
    viewer_pose_from_camera,
    viewer_pose_looking_at,
)
from umbra.modules.view3d.view3d import View3D
from umbra.modules.view3d.viewer_video import SNAPSHOT_SCALE
from umbra.runtime.harness import ModuleHarness

pytestmark = [pytest.mark.browser, pytest.mark.slow, needs_chromium]

#: the mount as designed: 3 cm forward, 5 cm above the tilt axis, camera z along head x
T_HEAD_LEFT = np.array(
    [[0.0, 0.0, 1.0, 0.03], [-1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.05], [0.0, 0.0, 0.0, 1.0]]
)
ERROR = offset_transform([0.02, -0.015, 0.01], [1.5, -2.0, 2.5])  # true = nominal . ERROR
FRAMES = {
    "base->table": transform_from_xyz_rpy_deg([0, 0, 0.25], [0, 0, 0]),
    "ptu_head->left": T_HEAD_LEFT,
}
# the principal point is off the image centre: the solve must use the camera's own intrinsics
MODEL = CameraModel(
    fx=820.0,
    fy=815.0,
    u0=331.0,
    v0=244.0,
    width=640,
    height=480,
    mount="ptu_head",
    frame="left",
    T_mount_camera=T_HEAD_LEFT,
)
CRATE = transform_from_xyz_rpy_deg([0.6, -0.2, 0.4], [0, 0, 0])
BLOCK = transform_from_xyz_rpy_deg([0.8, 0.2, 0.45], [0, 0, 25])
OBJECTS = SceneObjects(
    names=("crate", "block", "pipe"),
    kinds=("box", "box", "cylinder"),
    poses=np.stack([CRATE, BLOCK, transform_from_xyz_rpy_deg([0.45, 0.3, 0.3], [90, 0, 0])]),
    sizes=np.array([[0.3, 0.2, 0.3], [0.2, 0.2, 0.4], [0.03, 0.03, 0.4]]),
    colors=np.array([[160, 110, 60], [70, 110, 170], [200, 200, 200]]),
)


def features() -> np.ndarray:
    """Calibration points on the model's surfaces (world, m): the crate's and the block's top
    faces and two marks on the table."""
    crate = np.array([[0.12, 0.08, 0.15], [-0.12, 0.08, 0.15], [-0.12, -0.08, 0.15]])
    crate = np.vstack([crate, [0.12, -0.08, 0.15]])
    block = np.array([[0.08, 0.08, 0.2], [-0.08, -0.08, 0.2]])
    table = np.array([[0.35, -0.05, 0.25], [0.95, -0.35, 0.25]])
    return np.vstack(
        [
            crate @ CRATE[:3, :3].T + CRATE[:3, 3],
            block @ BLOCK[:3, :3].T + BLOCK[:3, 3],
            table,
        ]
    )


def ptu_poses() -> list[np.ndarray]:
    """T_world_head at three PTU poses 8 deg around the features' centroid."""
    pan0, tilt0 = aim(T_WORLD_PTU_BASE, features().mean(axis=0))
    spread = np.radians(8.0)
    return [
        T_WORLD_PTU_BASE @ T_base_head(pan0 + spread * np.cos(a), tilt0 + spread * np.sin(a))
        for a in np.pi / 2 + 2 * np.pi * np.arange(3) / 3
    ]


def true_camera(T_world_head: np.ndarray) -> np.ndarray:
    """The truly mounted camera's pose ``T_world_camera`` (the mount followed by the error)."""
    return T_world_head @ T_HEAD_LEFT @ ERROR


def true_pixels(T_world_head: np.ndarray) -> np.ndarray:
    """Where the truly mounted camera sees each feature (nan when it does not)."""
    bare = msgspec.structs.replace(MODEL, T_mount_camera=np.eye(4))
    frustum = frustum_from_model(bare, true_camera(T_world_head))
    return np.array([frustum.pixel_of(X) for X in features()])


def rendered(pixels: np.ndarray) -> np.ndarray:
    """The true camera's image: dark grey, a white dot with a red centre on every feature."""
    image = np.full((480, 640, 3), 40, np.uint8)
    for uv in pixels:
        if np.all(np.isfinite(uv)):
            centre = tuple(int(v) for v in np.round(uv * 16))
            cv2.circle(image, centre, 6 * 16, (255, 255, 255), -1, cv2.LINE_AA, shift=4)
            cv2.circle(image, centre, 2 * 16, (0, 0, 255), -1, cv2.LINE_AA, shift=4)
    return image


def _viewer_at(client, pose) -> bool:
    return bool(
        np.linalg.norm(client.camera.position - pose.position) < 1e-4
        and np.linalg.norm(client.camera.look_at - pose.look_at) < 1e-4
    )


class ViewerReports:
    """The camera the browser last reported (it reports after a frame has applied a move, and
    only then does a click's ray start there), when, and the rays of the clicks it sent."""

    def __init__(self, client) -> None:
        self.last = time.monotonic()
        self.position: np.ndarray | None = None
        self.rays: list[tuple[np.ndarray, np.ndarray]] = []
        client.camera.on_update(self._reported)

    def _reported(self, camera) -> None:
        self.position = np.array(camera.position)
        self.last = time.monotonic()

    def at(self, pose) -> bool:
        """The browser has reported its camera at ``pose`` and been quiet for a while."""
        return (
            self.position is not None
            and np.linalg.norm(self.position - pose.position) < 1e-4
            and time.monotonic() - self.last > 0.3
        )


def click_where(page, view, client, reports, canvas, pose, point, done, undo) -> None:
    """Click where a world point shows in the page, the viewer at ``pose``.

    The browser applies camera moves as it draws frames (slowly, with software WebGL) and a
    click is a ray from wherever its camera is then: wait until the flight is over and the
    browser has reported its camera at the pose; a click whose ray does not start at the pose
    all the same is undone and made again."""
    for _ in range(5):
        wait_for(
            lambda: not view.moving(client.client_id),
            20.0,
            "the viewer's flight to end",
            interval_s=0.05,
        )
        wait_for(
            lambda: _viewer_at(client, pose) and reports.at(pose),
            20.0,
            "the browser settled at the viewer pose",
            interval_s=0.05,
        )
        x, y = project_to_page(client, canvas, point)[0]
        rays = len(reports.rays)
        page.mouse.click(x, y)
        wait_for(lambda n=rays: len(reports.rays) > n, 20.0, "the click in Python", interval_s=0.05)
        if np.linalg.norm(reports.rays[-1][0] - pose.position) < 1e-4:
            wait_for(done, 20.0, "the click's effect", interval_s=0.05)
            return
        # the browser had not drawn the move yet: undo whatever that click did, click again
        with contextlib.suppress(AssertionError):  # it may never come: then nothing to undo
            wait_for(done, 2.0, "the late click's effect", 0.05)
        if done():
            undo()
    raise AssertionError("the browser's camera never settled at the viewer pose")


def test_pose_tool_in_the_page_recovers_a_wrong_mount(browser, tmp_path: Path) -> None:
    params = {"port": 0, "animation_s": 0.2, "max_fps": 20, "pose_tool_mount": "ptu_head->left"}
    with ModuleHarness(View3D, params, frames=FRAMES, output_dir=tmp_path) as h:
        module = h.module
        view = module.page
        tool = module.pose_tool
        page = browser.new_page(viewport={"width": 1500, "height": 760})
        block_outside_loopback(page)
        page.goto(module.address)
        client = wait_for(
            lambda: first_client(module), 20.0, "the browser to connect", interval_s=0.05
        )
        canvas = wait_for(
            lambda: canvas_box(page),
            20.0,
            "the docked panel",
            interval_s=0.05,
            ok=lambda c: c is not None and 0 < c.width < 1400,
        )
        assert canvas.width / canvas.height > MODEL.width / MODEL.height * (MODEL.fy / MODEL.fx)

        # -- three snapshots at three PTU poses, with the button in the page ----------------
        h.push("left_model", MODEL)
        h.push("objects", OBJECTS)
        heads = ptu_poses()
        reports = ViewerReports(client)
        handle_ray = tool.handle_ray

        def record(origin: np.ndarray, direction: np.ndarray) -> None:
            reports.rays.append((np.array(origin), np.array(direction)))
            handle_ray(origin, direction)

        tool.handle_ray = record  # every click's ray, as the page sent it
        seen_pixels = []
        for k, T_world_head in enumerate(heads):
            pixels = true_pixels(T_world_head)
            seen_pixels.append(pixels)
            h.push("left_pose", Pose(matrix=T_world_head, parent="base", child="ptu_head"))
            h.push("left_image", Image(pixels=rendered(pixels)))
            h.step(dt=0.05)
            believed = T_world_head @ T_HEAD_LEFT
            wait_for(
                lambda b=believed: (
                    view.cameras["left"].frustum is not None
                    and np.allclose(view.cameras["left"].frustum.T_world_camera, b)
                ),
                20.0,
                "the camera at its new PTU pose",
                interval_s=0.05,
            )
            sent = view.cameras["left"].frames_sent
            wait_for(
                lambda s=sent: view.cameras["left"].frames_sent >= s,
                20.0,
                "the frame",
                interval_s=0.05,
            )
            page.get_by_role("button", name="Snapshot left").click()
            wait_for(
                lambda n=k + 1: len(view.snapshots) == n, 20.0, f"snapshot {k + 1}", interval_s=0.05
            )
        ids = list(view.snapshots)
        assert ids == ["left-1", "left-2", "left-3"]
        assert {"/objects/crate", "/objects/block", "/workcell/table"} <= set(view.meshes)

        # -- click pairs: the feature in the snapshot's image, then on the model -----------
        model_view = viewer_pose_looking_at([0.3, -0.75, 1.25], [0.65, 0.0, 0.45], 0.75)
        model_errors = []
        for snapshot_id, T_world_head, pixels in zip(ids, heads, seen_pixels, strict=True):
            snapshot, frustum = view.snapshots[snapshot_id]
            np.testing.assert_allclose(snapshot.T_world_camera, T_world_head @ T_HEAD_LEFT)
            view.snapshot_dropdown.value = snapshot_id
            snapshot_view = viewer_pose_from_camera(frustum.T_world_camera, frustum.fov_y)
            depth = frustum.image_depth(SNAPSHOT_SCALE)
            for X, uv in zip(features(), pixels, strict=True):
                if not (np.all(np.isfinite(uv)) and 8 < uv[0] < 632 and 8 < uv[1] < 472):
                    continue
                eye = true_camera(T_world_head)
                first = ray_hit(eye[:3, 3], X - eye[:3, 3], list(view.meshes.values()))
                if first is None or np.linalg.norm(first.point - X) > 1e-6:
                    continue  # hidden from the camera
                page.get_by_role("button", name="View from snapshot").click()
                tool.mode.value = "image point"
                before = len(tool.tool.pairs)
                on_image = frustum.points_from_pixels(uv[None], depth)
                pair = click_where(
                    page,
                    view,
                    client,
                    reports,
                    canvas,
                    snapshot_view,
                    on_image,
                    lambda n=before: (
                        len(tool.tool.pairs) == n + 1 and tool.mode.value == "model point"
                    ),
                    undo=lambda: (
                        tool.tool.pairs.pop(),
                        setattr(tool.mode, "value", "image point"),
                    ),
                )
                pair = tool.tool.pairs[-1]
                assert pair.snapshot_id == snapshot_id
                # a page pixel is about 0.7 image pixels here
                assert np.linalg.norm(pair.pixel - uv) < 0.75, (pair.pixel, uv)
                assert tool.mode.value == "model point"
                view.set_viewer(client, model_view)  # the operator turns to the model
                click_where(
                    page,
                    view,
                    client,
                    reports,
                    canvas,
                    model_view,
                    X[None],
                    lambda: (
                        tool.tool.pairs[-1].point is not None and tool.mode.value == "image point"
                    ),
                    undo=lambda: (
                        setattr(tool.tool.pairs[-1], "point", None),
                        setattr(tool.mode, "value", "model point"),
                    ),
                )
                model_errors.append(float(np.linalg.norm(tool.tool.pairs[-1].point - X)))
                assert tool.mode.value == "image point"
        per_snapshot = {i: sum(p.snapshot_id == i for p in tool.tool.pairs) for i in ids}
        assert len(tool.tool.complete_pairs()) >= 8 and min(per_snapshot.values()) >= 2
        assert max(model_errors) < 2e-3  # a page pixel is about 1 mm on the model here

        # -- solve, residuals in the page, save ---------------------------------------------
        page.get_by_role("button", name="Solve mount").click()
        wait_for(lambda: "RMS" in tool.note.content, 20.0, "the solution", interval_s=0.05)
        result = tool.tool.result
        truth = T_HEAD_LEFT @ ERROR
        before = pose_error(T_HEAD_LEFT, truth)
        angle, offset = pose_error(tool.tool.corrected_mount(), truth)
        assert np.degrees(before[0]) > 3.0 and before[1] > 0.02
        assert np.degrees(angle) < 0.1 and offset < 0.002, (np.degrees(angle), offset)
        assert result.rms_px < 0.5
        rows = page.locator("tr").filter(has_text="left-")
        wait_for(
            lambda: rows.count() == len(tool.tool.complete_pairs()),
            20.0,
            "residual rows",
            interval_s=0.05,
        )
        assert rows.first.inner_text().split()[0] == "left-1"
        page.screenshot(path=str(tmp_path / "pose_tool.png"))
        page.get_by_role("button", name="Save mount").click()
        mount_file = tmp_path / "mount_ptu_head_left.yaml"
        wait_for(mount_file.exists, 20.0, "the saved mount", interval_s=0.05)
        saved = yaml.safe_load(mount_file.read_text())["frames"]["ptu_head->left"]
        np.testing.assert_allclose(saved["xyz"], tool.tool.corrected_mount()[:3, 3], atol=2e-6)
        wait_for(lambda: "saved" in tool.note.content, 20.0, "the saved note", interval_s=0.05)
        h.step(dt=0.05)
        mount = h.output("mount")
        assert (mount.parent, mount.child) == ("ptu_head", "left")
        angle, offset = pose_error(mount.matrix, truth)
        assert np.degrees(angle) < 0.1 and offset < 0.002
        page.close()
