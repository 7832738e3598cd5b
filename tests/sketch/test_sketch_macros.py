"""Every macro of the menu, planned, checked and played on the simulated cell through the
register and the kinematics; the outcome measured on the TRUE arm against the scene's truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from umbra.modules.sketch.macros import MENU, MacroError, check_options
from umbra.modules.sketch.session import Q_READY, Q_STOW, SessionError, SketchSession
from umbra.modules.sketch.stereo import StereoPair
from umbra.modules.world.scene_objects import SketchScene


def _session() -> SketchSession:
    return SketchSession(SketchScene.nominal(), seed=11)


def _place(session: SketchSession, kind: str, points, aim_at, zoom: float = 0.3, px=0.3):
    """Aim, snapshot and click the true ``points`` (noise ``px``; image b's clicks 5 px off
    their epipolar lines: the constraint puts them back)."""
    rng = np.random.default_rng(len(session.primitives))
    session.aim(aim_at, zoom=zoom)
    session.snapshot(render=False)
    a, b = session.true_pixels(np.asarray(points, dtype=float))
    pair = StereoPair.from_snapshot(session.snapshots[list(session.snapshots)[-1]])
    a = a + rng.normal(0.0, px, a.shape)
    b = b + 5.0 * pair.epipolar_line_b(a)[..., :2]
    return session.place(kind, a, b)


def _true_tool(session: SketchSession) -> np.ndarray:
    return session.table.fk(session.arm.q_true, session.T_flange_tool)


def _play(session: SketchSession, macro: str, prim=None, options=None):
    path = session.plan(macro, None if prim is None else prim.primitive_id, options)
    assert path.ok, f"{macro}: {path.reason}"
    log = session.play(path.path_id, timeout=60.0)
    assert log.mode[-1] == "done", f"{macro} ended {log.mode[-1]}"
    assert not any(log.guard), "the guard zeroed the command"
    return path


def _angle_deg(u, v) -> float:
    c = np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def test_the_menu_offers_each_macro_of_the_issue():
    assert [m for m, _ in MENU["none"]] == ["ready", "stow"]
    assert [m for m, _ in MENU["point"]] == ["move_to", "aim_along_ray"]
    assert [m for m, _ in MENU["line"]] == [
        "grab_pipe",
        "move_around_axis",
        "approach_side",
        "move_parallel",
        "aim_along_axis",
        "place_device",
    ]
    assert [m for m, _ in MENU["plane"]] == ["surface_scan", "follow_perimeter"]
    assert [m for m, _ in MENU["triad"]] == ["make_box"]


def test_canned_motions_stow_and_ready():
    s = _session()
    _play(s, "stow")
    assert np.max(np.abs(s.arm.q_true - Q_STOW)) < 0.01
    path = _play(s, "ready")
    assert np.max(np.abs(s.arm.q_true - Q_READY)) < 0.01
    # the cameras were slewed to watch the tool's goal as the motion started: it is seen at
    # the principal point of both images (the whole camera model at the current zoom)
    goal = path.T_base_tool[-1][:3, 3]
    for i, (cam, unit) in enumerate(zip(s.cameras, s.ptus, strict=True)):
        assert np.allclose(unit.angles, cam.aim(goal, s.zooms[i]))
        model, T = s.camera_state(i)
        uv = StereoPair(model.K, T, model.K, T, model.dist, model.dist).project("a", goal)
        assert np.linalg.norm(uv - [model.u0, model.v0]) < 2.0, uv


def test_point_macros_move_to_and_aim_along_the_ray():
    s = _session()
    target = s.scene.surface.center
    point = _place(s, "point", target[None, :], target, zoom=0.4)
    _play(s, "move_to", point, {"standoff": 0.06})
    T = _true_tool(s)
    assert np.linalg.norm(T[:3, 3] - (target + np.array([0, 0, 0.06]))) < 0.003
    assert _angle_deg(T[:3, 2], [0, 0, -1]) < 0.5
    eye = s.snapshots[point.snapshot_id].T_base_camera_a[:3, 3]
    _play(s, "aim_along_ray", point)
    T = _true_tool(s)
    ray = (target - eye) / np.linalg.norm(target - eye)
    assert _angle_deg(T[:3, 2], ray) < 0.5
    assert np.linalg.norm(T[:3, 3] - (target - 0.15 * ray)) < 0.003


def test_line_macros_approach_from_the_side_move_parallel_aim_along_the_axis():
    s = _session()
    pipe = s.scene.pipe
    line = _place(s, "line", pipe.ends, pipe.center)
    _play(s, "approach_side", line)
    v = s.judge.verdicts
    assert v.success("approach_side"), v.events
    T = _true_tool(s)
    assert np.degrees(np.arcsin(-T[2, 2])) == pytest.approx(20.0, abs=0.5)  # 20 deg below level
    level = np.array([T[0, 2], T[1, 2], 0.0])
    assert _angle_deg(level, [pipe.center[0], pipe.center[1], 0.0]) < 30.0  # from the arm's side
    s.grip("open")
    # move parallel: the tool translates by the line's vector, keeping its orientation
    s2 = _session()
    line2 = _place(s2, "line", pipe.ends, pipe.center)
    before = _true_tool(s2)
    _play(s2, "move_parallel", line2, {"fraction": 0.5})
    after = _true_tool(s2)
    shift = 0.5 * (line2.points[1] - line2.points[0])
    assert np.linalg.norm(after[:3, 3] - before[:3, 3] - shift) < 0.003
    turn = Rotation.from_matrix(after[:3, :3] @ before[:3, :3].T).magnitude()
    assert np.degrees(turn) < 0.5
    # aim along the axis of a line sloping down onto the pipe: tool z along the line,
    # `standoff` before its start (a level line at the table is beyond this arm's wrist)
    ends = np.stack([pipe.center + np.array([-0.1, 0.0, 0.15]), pipe.center])
    slope = _place(s2, "line", ends, pipe.center)
    _play(s2, "aim_along_axis", slope, {"standoff": 0.06})
    T = _true_tool(s2)
    start, end = slope.points
    direction = (end - start) / np.linalg.norm(end - start)
    assert _angle_deg(T[:3, 2], direction) < 0.5
    assert np.linalg.norm(T[:3, 3] - (start - 0.06 * direction)) < 0.003


def test_place_a_device_in_front_of_the_package():
    s = _session()
    s.grip("close")  # the device in hand
    edge = s.scene.package.front_bottom_edge
    line = _place(s, "line", edge, edge.mean(axis=0))
    path = _play(s, "place_device", line)
    assert path.gripper[-1] == 1.0  # released at the spot
    v = s.judge.verdicts
    assert v.success("place_device") and v.device_error_m < 0.01, v.events


@pytest.mark.parametrize("macro", ["surface_scan", "follow_perimeter"])
def test_plane_macros_scan_and_follow_the_rectangle(macro):
    s = _session()
    surface = s.scene.surface
    plane = _place(s, "plane", surface.corners[[1, 0, 3]], surface.center, zoom=0.4)
    _play(s, macro, plane)
    v = s.judge.verdicts
    assert v.success(macro), (v.coverage, v.perimeter_max_dev_m, v.perimeter_passed)
    if macro == "surface_scan":
        assert v.coverage >= 0.95
    else:
        assert v.perimeter_max_dev_m <= 0.005 and v.perimeter_passed >= 0.95


def test_triad_makes_a_box_without_motion():
    s = _session()
    pkg = s.scene.package
    sx, sy, sz = pkg.size
    R = np.array([[np.cos(pkg.yaw), -np.sin(pkg.yaw), 0], [np.sin(pkg.yaw), np.cos(pkg.yaw), 0]])
    R = np.vstack([R, [0, 0, 1]])
    corner = pkg.center + R @ [-sx / 2, -sy / 2, 0]
    points = [corner, corner + R @ [sx, 0, 0], corner + R @ [0, sy, 0], corner + R @ [0, 0, sz]]
    triad = _place(s, "triad", np.stack(points), pkg.center + np.array([0, 0, sz / 2]), zoom=0.2)
    q = s.arm.q_true.copy()
    box = s.make_box(triad.primitive_id)
    assert np.linalg.norm(box.T_base_box[:3, 3] - (pkg.center + np.array([0, 0, sz / 2]))) < 0.01
    assert np.allclose(box.size, pkg.size, atol=0.01)
    assert s.boxes[triad.primitive_id] is box and np.array_equal(s.arm.q_true, q)
    with pytest.raises(MacroError, match="no motion to plan"):
        s.plan("make_box", triad.primitive_id)


def test_bad_options_are_refused_before_planning():
    assert check_options("move_around_axis", {"angle_deg": 30}) == {"angle_deg": 30.0}
    for options, message in (
        ({"angle": 30}, "has no option 'angle'; its options: angle_deg"),
        ({"angle_deg": float("nan")}, r"angle_deg must be a number within -180 \.\. 180"),
        ({"angle_deg": 1e308}, r"angle_deg must be a number within -180 \.\. 180"),
    ):
        with pytest.raises(MacroError, match=message):
            check_options("move_around_axis", options)
    with pytest.raises(MacroError, match="'grab_pipe' has no option 'standoff'; its options: none"):
        check_options("grab_pipe", {"standoff": 0.1})
    s = _session()
    s.snapshot(render=False)
    with pytest.raises(SessionError, match=r"script step 0.0:fly: unknown VCR action"):
        s.play(s.plan("stow").path_id, [(0.0, "fly", {})])
    with pytest.raises(SessionError, match=r"aim at .* outside the unit's travel"):
        s.aim([5.0, 5.0, 5.0])
    assert np.array_equal(s.arm.q_true, Q_READY)  # nothing moved
