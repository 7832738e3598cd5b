"""The View3D module without a browser: sketch items into the scene file, and back at start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.poll import wait_for
from umbra.connectors.errors import UserError
from umbra.connectors.sketch_messages import SketchBox, SketchPrimitive, StereoSnapshot
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.scene_file import load_scene
from umbra.modules.view3d.view3d import View3D
from umbra.runtime.harness import ModuleHarness

FRAMES = {"base->table": transform_from_xyz_rpy_deg([0, 0, 0.25], [0, 0, 0])}


def test_sketch_items_are_kept_saved_and_reloaded(tmp_path: Path) -> None:
    K = np.array([[500.0, 0, 32], [0, 500.0, 24], [0, 0, 1]])
    image = np.full((48, 64, 3), 90, np.uint8)
    T_a = transform_from_xyz_rpy_deg([-0.15, 0, 1.5], [180, 0, 0])
    T_b = transform_from_xyz_rpy_deg([0.15, 0, 1.5], [180, 0, 0])
    T_box = transform_from_xyz_rpy_deg([0.5, 0.2, 0.1], [0, 0, 15])  # in the table frame
    first = tmp_path / "first"
    with ModuleHarness(View3D, {"port": 0}, frames=FRAMES, output_dir=first) as h:
        h.push(
            "snapshot",
            StereoSnapshot(
                snapshot_id="s1",
                image_a=image,
                image_b=image,
                K_a=K,
                K_b=K,
                T_base_camera_a=T_a,
                T_base_camera_b=T_b,
            ),
        )
        h.push(
            "box",
            SketchBox(box_id="b1", T_base_box=T_box, size=np.array([0.2, 0.1, 0.1]), frame="table"),
        )
        h.push(
            "primitive",
            SketchPrimitive(
                primitive_id="l1", kind="line", points=np.array([[0, 0, 0.3], [0.4, 0, 0.3]])
            ),
        )
        h.step(dt=0.05)
        plane = np.array([[0.3, -0.2, 0.0], [0.5, -0.2, 0.0], [0.5, 0.1, 0.0]])  # table frame
        h.push(
            "primitive",
            SketchPrimitive(primitive_id="pl1", kind="plane", points=plane, frame="table"),
        )
        h.step(dt=0.05)
        page = h.module.page
        nodes = page.server.scene._handle_from_node_name  # viser's scene tree, by node name
        wait_for(
            lambda: (
                len(page.snapshots) == 2
                and "/sketch/boxes/b1" in page.meshes
                and {"/sketch/primitives/l1/edges", "/sketch/primitives/pl1/plane"} <= set(nodes)
            ),
            10,
            "items on the page",
            interval_s=0.05,
        )
        assert page.snapshot_dropdown.options == ("s1/a", "s1/b")
        np.testing.assert_allclose(page.snapshots["s1/b"][1].T_world_camera, T_b)
        # the box came in the table frame: it is drawn in base, 25 cm higher
        corners = page.meshes["/sketch/boxes/b1"].vertices
        assert corners[:, 2].min() == pytest.approx(0.25 + 0.1 - 0.05)
        path = Path(h.module.summary()["scene_file"])
        wait_for(lambda: path.exists() and "pl1" in path.read_text(), 10, "saved", interval_s=0.05)
    scene = load_scene(path)
    assert sorted(scene.snapshots) == ["s1/a", "s1/b"] and list(scene.boxes) == ["b1"]
    assert sorted(scene.primitives) == ["l1", "pl1"]
    # the plane came in the table frame: saved in base, 25 cm higher, a parallelogram
    np.testing.assert_allclose(scene.primitives["pl1"].points[:, 2], 0.25)
    np.testing.assert_allclose(scene.primitives["pl1"].plane_corners()[3], [0.3, 0.1, 0.25])
    with ModuleHarness(
        View3D, {"port": 0, "load_scene": str(path)}, frames=FRAMES, output_dir=tmp_path / "second"
    ) as h:
        page = h.module.page
        wait_for(
            lambda: (
                len(page.snapshots) == 2
                and "/sketch/boxes/b1" in page.meshes
                and "/sketch/primitives/pl1/plane" in page.server.scene._handle_from_node_name
            ),
            10,
            "items reloaded",
            interval_s=0.05,
        )


def test_bad_parameters_and_scene_files_are_user_errors(tmp_path: Path) -> None:
    with (
        pytest.raises(UserError, match="pose_tool_mount"),
        ModuleHarness(View3D, {"port": 0, "pose_tool_mount": "camera"}),
    ):
        pass
    bad = tmp_path / "scene.json"
    bad.write_text("{}")
    with (
        pytest.raises(UserError, match="not a scene file"),
        ModuleHarness(View3D, {"port": 0, "load_scene": str(bad)}),
    ):
        pass


def test_pose_tool_widgets_from_clicks_to_the_mount_output(tmp_path: Path) -> None:
    from umbra.connectors.messages import CameraModel, Image
    from umbra.modules.view3d.geometry import (
        frustum_from_model,
        matrix_from_wxyz,
        viewer_pose_looking_at,
    )

    look = viewer_pose_looking_at([0.6, -0.8, 1.2], [0.6, 0.0, 0.25], 0.8)
    T_cam = np.eye(4)
    T_cam[:3, :3] = matrix_from_wxyz(look.wxyz)
    T_cam[:3, 3] = look.position
    frames = {**FRAMES, "base->cam_left": T_cam, "mount->cam": np.eye(4)}
    model = CameraModel(
        fx=600.0,
        fy=600.0,
        u0=320.0,
        v0=240.0,
        width=640,
        height=480,
        mount="cam_left",
        frame="left",
    )
    params = {"port": 0, "pose_tool_mount": "mount->cam"}
    with ModuleHarness(View3D, params, frames=frames, output_dir=tmp_path) as h:
        h.push("left_model", model)
        h.push("left_image", Image(pixels=np.zeros((480, 640, 3), np.uint8)))
        h.step(dt=0.05)
        h.module.push.send(dict(h.module.push.latest))  # what the sender thread does for a browser
        page, widgets = h.module.page, h.module.pose_tool
        snapshot = page.take_snapshot("left")
        assert snapshot is not None
        h.step(dt=0.05)
        wait_for(lambda: snapshot.id in page.snapshots, 10, "the snapshot", interval_s=0.05)
        frustum = frustum_from_model(model, T_cam)
        depth = widgets.tool.image_depth(snapshot.id)
        for X in ([0.3, -0.2, 0.25], [0.65, -0.2, 0.25], [0.65, 0.3, 0.25], [0.35, 0.25, 0.25]):
            X = np.array(X)
            on_image = frustum.points_from_pixels(frustum.pixel_of(X)[None], depth)[0]
            origin = T_cam[:3, 3] + 0.5 * (on_image - T_cam[:3, 3])
            widgets.mode.value = "image point"
            widgets.handle_ray(origin, on_image - origin)
            assert widgets.mode.value == "model point"  # the next click goes to the model
            widgets.handle_ray(X + np.array([0, 0, 1.0]), np.array([0, 0, -1.0]))  # on the table
            assert widgets.mode.value == "image point"
        assert len(widgets.tool.complete_pairs()) == 4
        widgets.solve()
        assert "RMS" in widgets.note.content and widgets.tool.result.rms_px < 1e-3
        np.testing.assert_allclose(widgets.tool.corrected_mount(), np.eye(4), atol=1e-6)
        widgets.save()
        assert (tmp_path / "mount_mount_cam.yaml").exists()
        h.step(dt=0.05)
        sent = h.output("mount")
        assert (sent.parent, sent.child) == ("mount", "cam")
        np.testing.assert_allclose(sent.matrix, np.eye(4), atol=1e-6)


def test_scene_objects_are_drawn_and_pickable(tmp_path: Path) -> None:
    from umbra.connectors.scene_messages import SceneObjects

    poses = np.stack(
        [
            transform_from_xyz_rpy_deg([0.6, 0.0, 0.3], [90, 0, 0]),
            transform_from_xyz_rpy_deg([0.6, 0.5, 0.2], [0, 0, 30]),
        ]
    )
    objects = SceneObjects(
        names=("pipe", "package"),
        kinds=("cylinder", "box"),
        poses=poses,
        sizes=np.array([[0.04, 0.04, 0.6], [0.3, 0.2, 0.2]]),
        colors=np.array([[200, 200, 200], [150, 100, 50]]),
    )
    with ModuleHarness(View3D, {"port": 0}, frames=FRAMES, output_dir=tmp_path) as h:
        h.push("objects", objects)
        h.step(dt=0.05)
        h.module.push.send(dict(h.module.push.latest))  # what the sender thread does for a browser
        meshes = h.module.page.meshes
        assert {"/objects/pipe", "/objects/package"} <= set(meshes)
        from umbra.modules.view3d.geometry import ray_hit

        hit = ray_hit([0.6, 0.0, 1.0], [0, 0, -1.0], list(meshes.values()))
        assert hit.name == "/objects/pipe" and hit.point[2] == pytest.approx(0.34, abs=1e-3)


def test_a_malformed_solid_spoils_only_itself(tmp_path: Path) -> None:
    """A door whose axes are a reflection (as a world may send) is the same box and is drawn;
    a scaled pose is not drawn; the other solids and the cameras are drawn in the same
    update."""
    from umbra.connectors.messages import CameraModel, Pose
    from umbra.connectors.scene_messages import SceneObjects
    from umbra.modules.view3d.geometry import ray_hit

    mirrored = np.eye(4)
    mirrored[:3, :3] = np.column_stack([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    mirrored[:3, 3] = [0.9, -0.4, 0.5]
    scaled = transform_from_xyz_rpy_deg([0.6, 0.5, 0.2], [0, 0, 30])
    scaled[:3, :3] *= 2.0
    objects = SceneObjects(
        names=("door", "package", "crate"),
        kinds=("box", "box", "box"),  # words made in-process: SceneObjects makes them SolidKinds
        poses=np.stack([mirrored, scaled, transform_from_xyz_rpy_deg([0.3, 0, 0.1], [0, 0, 0])]),
        sizes=np.array([[0.4, 0.02, 0.6], [0.3, 0.2, 0.2], [0.1, 0.1, 0.1]]),
        colors=np.array([[60, 110, 170], [150, 100, 50], [90, 90, 90]]),
    )
    model = CameraModel(fx=600.0, fy=600.0, u0=320.0, v0=240.0, width=640, height=480)
    params = {"port": 0}
    with ModuleHarness(View3D, params, frames=FRAMES, output_dir=tmp_path) as h:
        h.push("objects", objects)
        h.push("left_model", model)
        T_left = transform_from_xyz_rpy_deg([0, 0, 1.5], [180, 0, 0])
        h.push("left_pose", Pose(matrix=T_left, parent="base", child="left"))
        h.step(dt=0.05)
        h.module.push.send(dict(h.module.push.latest))  # what the sender thread does for a browser
        meshes = h.module.page.meshes
        assert {"/objects/door", "/objects/crate"} <= set(meshes)
        assert "/objects/package" not in meshes
        # the mirrored door is the same slab: 2 cm thick along world x at x = 0.9
        hit = ray_hit([2.0, -0.4, 0.5], [-1.0, 0, 0], [meshes["/objects/door"]])
        assert hit.point[0] == pytest.approx(0.91, abs=1e-9)
        assert h.module.page.cameras["left"].frustum is not None
        assert h.module.page.cameras["wrist"].frustum is None  # no wrist camera: none drawn
        assert h.module.summary()["update_parts_failed"] == 0


def test_only_fed_cameras_are_offered_frames_are_named_and_the_stage_is_shown(
    tmp_path: Path,
) -> None:
    from umbra.connectors.messages import CameraModel, JointState, Pose, Status
    from umbra.modules.view3d.view3d_push import stage_line

    model = CameraModel(fx=600.0, fy=600.0, u0=320.0, v0=240.0, width=640, height=480)
    frames = {**FRAMES, "flange->tool": transform_from_xyz_rpy_deg([0, 0, 0.14], [0, 0, 0])}
    q = np.radians([0.0, 45.6, -182.7, 0.0, -42.9, 0.0])
    with ModuleHarness(View3D, {"port": 0}, frames=frames, output_dir=tmp_path) as h:
        page = h.module.page
        assert page.sliders == {} and page.view_buttons == {}  # nothing fed yet: none offered
        h.push("left_model", model)
        T_left = transform_from_xyz_rpy_deg([0, 0, 1.5], [180, 0, 0])
        h.push("left_pose", Pose(matrix=T_left, parent="base", child="left"))
        h.push("joint_state", JointState(names=h.module.params.joint_names, position=q))
        status = Status(
            stage="assist", message="halted", assist=True, reason="snake failure: featureless"
        )
        h.push("stage", status)
        h.step(dt=0.05)
        h.module.push.send(dict(h.module.push.latest))  # what the sender thread does for a browser
        # the graph feeds the left camera only: only it has a folder and a "View from" button
        assert set(page.sliders) == set(page.view_buttons) == {"left"}
        # frames named where they are: the table (25 cm above base), the tool, the camera
        text, at = page.labels["table"]
        assert text == "table" and np.allclose(at, [0, 0, 0.25])
        T_tool = h.module.params.table.fk(q) @ frames["flange->tool"]
        assert np.allclose(page.labels["tool"][1], T_tool[:3, 3])
        # the camera's name under its drawn image, never over the video: in the camera frame
        # (z forward, y down) in front of the lens, below the image's bottom edge
        text, at = page.labels["camera left"]
        in_camera = np.linalg.inv(T_left) @ np.append(at, 1.0)
        frustum = page.cameras["left"].frustum
        depth = frustum.image_depth(0.15)
        half_height = depth * np.tan(frustum.fov_y / 2)
        assert text == "left" and in_camera[2] == pytest.approx(depth)
        assert in_camera[1] == pytest.approx(1.5 * half_height) and abs(in_camera[0]) < 1e-9
        # pushed again with nothing moved: no label is sent again; a moved camera's is
        sent = page.labels_sent
        for _ in range(3):
            h.module.push.send(dict(h.module.push.latest))
        assert page.labels_sent == sent
        T_moved = transform_from_xyz_rpy_deg([0.1, 0, 1.5], [180, 0, 0])
        h.push("left_pose", Pose(matrix=T_moved, parent="base", child="left"))
        h.step(dt=0.05)
        h.module.push.send(dict(h.module.push.latest))
        assert page.labels_sent == sent + 1
        assert page.labels["camera left"][1][0] == pytest.approx(at[0] + 0.1)
        # the task's state line, with why it stopped
        line = "assist: halted (asks the operator: snake failure: featureless)"
        assert stage_line(status) == line
        assert page.stage_note.content == f"**stage**: {line}"
