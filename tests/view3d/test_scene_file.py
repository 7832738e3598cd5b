"""The 3-D view's scene file: round trip, atomic save, and bad files; sketch messages to items."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from umbra.connectors.errors import UserError
from umbra.connectors.sketch_messages import SketchBox, SketchPrimitive, StereoSnapshot
from umbra.modules.geometry.transforms import transform_from_xyz_rpy_deg
from umbra.modules.view3d.scene_file import (
    Scene,
    SceneBox,
    ScenePrimitive,
    SceneSnapshot,
    images_dir,
    load_scene,
    save_scene,
)
from umbra.modules.view3d.scene_messages import box_item, primitive_item, snapshot_items


def sample_scene() -> Scene:
    rng = np.random.default_rng(4)
    image = rng.integers(0, 255, (48, 64, 3), dtype=np.uint8)
    K = np.array([[80.0, 0, 32], [0, 80.0, 24], [0, 0, 1]])
    scene = Scene(frame="base")
    T_cam = transform_from_xyz_rpy_deg([0.1, -0.5, 1.2], [170, 3, 40])
    scene.snapshots["s1/a"] = SceneSnapshot("s1/a", "cam_left", T_cam, K, image)
    T_box = transform_from_xyz_rpy_deg([0.6, 0.1, 0.35], [0, 0, 25])
    scene.boxes["box1"] = SceneBox("box1", T_box, np.array([0.3, 0.2, 0.1]))
    line = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]])
    scene.primitives["l1"] = ScenePrimitive("l1", "line", line, np.array([[0, 1]]))
    plane = np.array([[0, 0, 0.3], [0.2, 0, 0.3], [0.2, 0.1, 0.3]])
    scene.primitives["pl"] = ScenePrimitive("pl", "plane", plane, np.array([[0, 1], [1, 2]]))
    return scene


def test_round_trip_keeps_every_item_exactly(tmp_path: Path) -> None:
    scene = sample_scene()
    path = save_scene(scene, tmp_path / "scene.json")
    back = load_scene(path)
    assert back.frame == "base" and back.count() == 4
    a, b = scene.snapshots["s1/a"], back.snapshots["s1/a"]
    assert b.camera == "cam_left"
    np.testing.assert_array_equal(a.image, b.image)  # PNG is lossless
    np.testing.assert_allclose(a.T_world_camera, b.T_world_camera, atol=0)
    np.testing.assert_allclose(a.K, b.K, atol=0)
    np.testing.assert_allclose(back.boxes["box1"].size, [0.3, 0.2, 0.1])
    np.testing.assert_allclose(back.boxes["box1"].T_world_box, scene.boxes["box1"].T_world_box)
    np.testing.assert_allclose(back.primitives["l1"].points, scene.primitives["l1"].points)
    np.testing.assert_allclose(
        back.primitives["pl"].plane_corners(),
        [[0, 0, 0.3], [0.2, 0, 0.3], [0.2, 0.1, 0.3], [0, 0.1, 0.3]],
    )
    assert (images_dir(path) / "s1_a.png").exists()
    assert not list(tmp_path.glob("*.tmp"))
    # saving again (one item more) keeps the images and replaces the file whole
    scene.boxes["box2"] = SceneBox("box2", np.eye(4), np.array([0.1, 0.1, 0.1]))
    save_scene(scene, path)
    assert load_scene(path).count() == 5


def _edit(path: Path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d["boxes"][0].update(size=[0.3, -0.2, 0.1]), "boxes[0] ('box1').size"),
        (lambda d: d["boxes"][0]["T_world_box"][0].__setitem__(0, 2.0), "rigid transform"),
        (lambda d: d["primitives"][0].update(kind="circle"), "primitives[0] ('l1').kind"),
        (lambda d: d["primitives"][0].update(edges=[[0, 5]]), "vertex index"),
        (lambda d: d["snapshots"][0].update(image="../x.png"), "file name"),
        (lambda d: d["snapshots"][0].update(image="gone.png"), "cannot read"),
        (lambda d: d["snapshots"][0].update(width=65), "expected 65x48 px"),
        (lambda d: d.update(version=7), "version 1"),
        (lambda d: d.update(extra=1), "not a scene file"),
        (lambda d: d["snapshots"][0].update(K=[[1, 0], [0, 1]]), "3x3"),
    ],
)
def test_bad_scene_files_say_what_and_where(tmp_path: Path, change, message) -> None:
    path = save_scene(sample_scene(), tmp_path / "scene.json")
    _edit(path, change)
    with pytest.raises(UserError) as failure:
        load_scene(path)
    assert message in str(failure.value) and str(path) in str(failure.value)


def test_truncated_and_missing_files(tmp_path: Path) -> None:
    path = save_scene(sample_scene(), tmp_path / "scene.json")
    path.write_text(path.read_text()[:40])
    with pytest.raises(UserError, match="not a scene file"):
        load_scene(path)
    with pytest.raises(UserError, match="cannot read"):
        load_scene(tmp_path / "none.json")


def test_sketch_messages_become_scene_items_in_the_world() -> None:
    T_world_base = transform_from_xyz_rpy_deg([0.0, 0.0, 0.1], [0, 0, 90])
    image = np.zeros((48, 64, 3), np.uint8)
    K = np.array([[80.0, 0, 32], [0, 80.0, 24], [0, 0, 1]])
    T_a = transform_from_xyz_rpy_deg([-0.15, 0, 1.5], [180, 0, 0])
    snap = StereoSnapshot(
        snapshot_id="s7",
        image_a=image,
        image_b=image + 1,
        K_a=K,
        K_b=K,
        T_base_camera_a=T_a,
        T_base_camera_b=np.eye(4),
        camera_a_name="left",
        camera_b_name="right",
    )
    a, b = snapshot_items(snap, T_world_base)
    assert (a.id, b.id, a.camera) == ("s7/a", "s7/b", "left")
    np.testing.assert_allclose(a.T_world_camera, T_world_base @ T_a)
    assert b.image[0, 0, 0] == 1
    box = box_item(
        SketchBox(box_id="b", T_base_box=np.eye(4), size=np.array([1, 2, 3.0])), T_world_base
    )
    np.testing.assert_allclose(box.T_world_box, T_world_base)
    with pytest.raises(ValueError, match="positive"):
        box_item(SketchBox(box_id="b", T_base_box=np.eye(4), size=np.array([1, 0, 3.0])), np.eye(4))
    triad = primitive_item(
        SketchPrimitive(primitive_id="t", kind="triad", points=np.eye(4, 3)), T_world_base
    )
    np.testing.assert_array_equal(triad.edges, [[0, 1], [0, 2], [0, 3]])
    np.testing.assert_allclose(triad.points[1], [-1.0, 0.0, 0.1], atol=1e-12)  # y turned to -x
