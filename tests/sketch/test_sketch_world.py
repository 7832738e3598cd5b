"""The sketch scene: its rendering, and the world's verdicts against the truth."""

from __future__ import annotations

import numpy as np

from umbra.modules.geometry.transforms import rot_z
from umbra.modules.sketch.session import SketchSession
from umbra.modules.sketch.tool_poses import DOWN, tool_pose
from umbra.modules.world.scene_objects import SketchScene, targets_from_objects
from umbra.modules.world.sketch_judge import SketchJudge


def test_rendered_pipe_is_where_the_camera_model_projects_it():
    session = SketchSession(SketchScene.nominal(), seed=0, image_noise=0.0)
    session.aim(session.scene.pipe.center, zoom=0.3)
    snap = session.snapshot()
    a, _ = session.true_pixels(session.scene.pipe.center[None, :])
    u, v = np.round(a[0]).astype(int)
    b, g, r = snap.image_a[v, u].astype(int)
    assert r > 120 and r > 2 * g and r > 2 * b  # the pipe is red; the table is not
    assert np.any(snap.image_a != snap.image_b)


def test_targets_match_the_scene_truth():
    scene = SketchScene.random(np.random.default_rng(5))
    t = targets_from_objects(scene.message())
    assert np.allclose(np.sort(t["pipe"], axis=0), np.sort(scene.pipe.ends, axis=0))
    assert np.allclose(t["hinge"], [scene.door.hinge_top, scene.door.hinge])
    assert np.allclose(t["package_edge"], scene.package.front_bottom_edge)


def test_grasp_judged_in_mm_and_degrees():
    scene = SketchScene.nominal()
    judge = SketchJudge(scene)
    pipe = scene.pipe
    T = tool_pose(
        pipe.center + np.array([0.003, 0.0, 0.0]), DOWN, rot_z(np.radians(2.0))[:3, :3] @ pipe.axis
    )
    judge.update(T, 1.0)
    judge.update(T, 0.0)
    v = judge.verdicts
    assert abs(v.grasp_distance_m - 0.003 * abs(np.cross([1, 0, 0], pipe.axis)[2])) < 1e-9
    assert abs(np.degrees(v.grasp_angle_rad) - 2.0) < 1e-6 and v.success("grab_pipe")
    judge = SketchJudge(scene)
    T[:3, 3] += [0.0, 0.0, 0.006]
    judge.update(T, 1.0)
    judge.update(T, 0.0)
    assert not judge.verdicts.success("grab_pipe")


def test_door_follows_a_held_handle_and_is_lost_when_the_tool_leaves_it():
    scene = SketchScene.nominal()
    judge = SketchJudge(scene)
    door = scene.door
    T = tool_pose(door.handle_center, DOWN, door.handle_axis)
    judge.update(T, 1.0)
    judge.update(T, 0.0)
    assert judge.verdicts.handle_held
    for angle in np.radians(np.linspace(0.0, 40.0, 41)):
        turned = judge.scene.with_door_angle(angle).door
        judge.update(tool_pose(turned.handle_center, DOWN, turned.handle_axis), 0.0)
    assert abs(np.degrees(judge.scene.door.angle) - 40.0) < 1e-6
    T = tool_pose(
        judge.scene.door.handle_center + np.array([0.0, 0.0, 0.03]), DOWN, door.handle_axis
    )
    judge.update(T, 0.0)  # pulled up 3 cm: the gripper slips off the bar
    v = judge.verdicts
    assert v.handle_lost and not v.success("move_around_axis")
