"""Macro menus and the plan checks: reach, joint limits, singularities, speed."""

from __future__ import annotations

import numpy as np
import pytest

from umbra.connectors.sketch_messages import Macro, SketchPrimitive
from umbra.modules.arm.dh import puma560
from umbra.modules.geometry.transforms import translation
from umbra.modules.sketch.macros import MacroError, macro_keys, menu_for
from umbra.modules.sketch.path_check import PathLimits, plan_path
from umbra.modules.sketch.session import Q_READY
from umbra.modules.world.scene_objects import SketchScene

TABLE = puma560()
T_FT = translation(0, 0, 0.14)
T_READY = TABLE.fk(Q_READY, T_FT)


def _line(points) -> SketchPrimitive:
    return SketchPrimitive(primitive_id="L", kind="line", points=np.asarray(points, dtype=float))


def _plan(macro, prim, limits=None, q=Q_READY, options=None):
    limits = limits or PathLimits()
    keys = macro_keys(macro, prim, TABLE.fk(q, T_FT), 1.0, options, q_ready=Q_READY)
    return plan_path(keys, TABLE, T_FT, q, 1.0, limits, path_id="p")


def test_menus_by_primitive():
    assert [m for m, _ in menu_for(None)] == ["ready", "stow"]
    assert "grab_pipe" in dict(menu_for(_line([[0, 0, 0], [1, 0, 0]])))
    with pytest.raises(MacroError, match="'surface_scan' is not on the menu for a line"):
        macro_keys(Macro.SURFACE_SCAN, _line([[0, 0, 0], [1, 0, 0]]), T_READY, 1.0)


def test_grab_pipe_plan_is_checked_and_ends_on_the_grasp():
    pipe = SketchScene.nominal().pipe
    path = _plan("grab_pipe", _line(pipe.ends))
    assert path.ok, path.reason
    T_end = TABLE.fk(path.joints[-1], T_FT)
    assert np.linalg.norm(T_end[:3, 3] - pipe.center) < 1e-6
    assert abs(T_end[:3, 0] @ pipe.axis) > 1 - 1e-9 and T_end[2, 2] < -1 + 1e-9
    assert path.gripper[0] == 1.0 and path.gripper[-1] == 0.0 and path.gripper[-2] == 1.0
    assert np.allclose(path.joints[0], Q_READY)
    # the playing rate keeps the tool within its speed limit and the joints within half theirs
    assert path.checks["peak_tool_speed"] <= 0.08 + 1e-9
    dq = np.abs(np.diff(path.joints, axis=0)) / np.diff(path.s)[:, None] * path.checks["rate"]
    assert np.all(dq.max(axis=0) <= 0.5 * TABLE.qd_max + 1e-9)


def test_unreachable_pipe_is_refused_for_reach():
    path = _plan("grab_pipe", _line([[1.6, -0.1, 0.3], [1.6, 0.1, 0.3]]))
    assert not path.ok and path.reason.startswith("reach: ")


def test_joint_limit_violating_path_is_refused():
    q_bad = Q_READY.copy()
    q_bad[4] = np.radians(99.0)  # wrist within 1 deg of its +100 deg limit
    keys = macro_keys(Macro.READY, None, T_READY, 1.0, q_ready=q_bad)
    path = plan_path(keys, TABLE, T_FT, Q_READY, 1.0, PathLimits(), path_id="p")
    assert not path.ok
    assert path.reason.startswith("joint limits: j5 comes within 1.0 deg of its limit")


def test_path_through_a_singularity_is_refused():
    # the arm stretched straight up (elbow singularity) is on the joint line to this target
    q_up = np.radians([0.0, 90.0, -90.0, 0.0, 0.0, 0.0])
    keys = macro_keys(Macro.READY, None, T_READY, 1.0, q_ready=q_up)
    path = plan_path(keys, TABLE, T_FT, Q_READY, 1.0, PathLimits(), path_id="p")
    assert not path.ok and path.reason.startswith("singularity: the Jacobian's smallest")


def test_too_slow_a_path_is_refused_for_speed():
    pipe = SketchScene.nominal().pipe
    path = _plan("grab_pipe", _line(pipe.ends), PathLimits(min_rate=5.0))
    assert not path.ok and path.reason.startswith("speed: the tool speed limit allows only")


def test_move_around_axis_sweeps_about_the_line_by_the_right_hand_rule():
    door = SketchScene.nominal().door
    grab = _plan(
        "grab_pipe",
        _line(
            [
                door.handle_center - 0.05 * door.handle_axis,
                door.handle_center + 0.05 * door.handle_axis,
            ]
        ),
    )
    assert grab.ok, grab.reason
    q1 = grab.joints[-1]
    hinge = _line([door.hinge_top, door.hinge])  # pointing down: opens towards the arm
    keys = macro_keys(Macro.MOVE_AROUND_AXIS, hinge, TABLE.fk(q1, T_FT), 0.0, {"angle_deg": 85})
    path = plan_path(keys, TABLE, T_FT, q1, 0.0, PathLimits(), path_id="p")
    assert path.ok, path.reason
    start, end = TABLE.fk(path.joints[0], T_FT)[:3, 3], TABLE.fk(path.joints[-1], T_FT)[:3, 3]
    r0, r1 = (start - door.hinge)[:2], (end - door.hinge)[:2]
    turned = np.degrees(np.arctan2(r1[1], r1[0]) - np.arctan2(r0[1], r0[0]))
    turned = (turned + 180.0) % 360.0 - 180.0
    assert turned == pytest.approx(-85.0, abs=1e-3)  # about -z: clockwise seen from above
    assert np.all(path.gripper == 0.0)


def test_a_wrist_that_must_turn_over_gets_a_joint_transit_the_kinematics_can_follow():
    from umbra.modules.sketch.transit import twist_round_trip_error

    pipe = SketchScene.nominal().pipe
    path = _plan("approach_side", _line(pipe.ends))
    assert path.ok, path.reason
    n = int(path.checks["transit_samples"])
    assert n > 10
    # the wrist bend (j5) changes sign on the way: through its singularity, in joint space
    assert path.joints[0, 4] < -0.5 and path.joints[n, 4] > 0.5
    errors = [
        twist_round_trip_error(TABLE, T_FT, path.joints[i], path.joints[i + 1] - path.joints[i])
        for i in range(n)
    ]
    assert max(errors) <= 0.1
    # after the transit the approach is a straight tool line onto the grasp
    tool = np.array([TABLE.fk(q, T_FT)[:3, 3] for q in path.joints[n:]])
    direction = (tool[-1] - tool[0]) / np.linalg.norm(tool[-1] - tool[0])
    off_line = np.cross(tool - tool[0], direction)
    assert np.abs(off_line).max() < 1e-6
