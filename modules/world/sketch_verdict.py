"""The end of a macro in words an operator reads: success or miss, with the judge's numbers.

:func:`macro_verdict` turns the :class:`~umbra.modules.world.sketch_judge.Verdicts` measured while a
macro played into ``(outcome, text, figures)``: ``outcome`` is ``Outcome.SUCCEEDED``, ``MISSED``
or ``DONE`` (a macro the world does not judge: ready, stow, move_to, ...), ``text`` says what
happened with the numbers (mm, deg, %), ``figures`` holds them (mm, deg, 1). Criteria are the
judge's own (:meth:`Verdicts.success`): this module only words them.
"""

from __future__ import annotations

import math

import numpy as np

from umbra.connectors.sketch_messages import Macro
from umbra.connectors.states import Outcome
from umbra.modules.world.sketch_judge import (
    COVERAGE_GOAL,
    DEVICE_TOLERANCE_M,
    DOOR_GOAL_RAD,
    GRASP_MACROS,
    GRASP_TOLERANCE_M,
    GRASP_TOLERANCE_RAD,
    PERIMETER_TOLERANCE_M,
    Verdicts,
)

#: macros that end when the gripper opens (the device is set down)
RELEASE_MACROS = (Macro.PLACE_DEVICE,)


def macro_verdict(macro: Macro, v: Verdicts) -> tuple[Outcome, str, dict[str, float]]:
    """``(outcome, text, figures)`` of ``macro`` from what the judge measured (see module
    docstring). Call it when the macro ended: the gripper closed (grasp macros), the device was
    released, or the path was played to its end."""
    ok = v.success(macro)
    outcome = Outcome.SUCCEEDED if ok else Outcome.MISSED
    if macro in GRASP_MACROS:
        return _grasp(outcome, v)
    if macro == Macro.MOVE_AROUND_AXIS:
        angle = math.degrees(v.door_max_rad)
        goal = math.degrees(DOOR_GOAL_RAD)
        held = "the handle lost on the way" if v.handle_lost else "handle held"
        if not v.handle_held and not v.handle_lost and v.door_max_rad <= 0.0:
            held = "the handle was never caught"
        text = (
            f"door opened to {angle:.1f} deg ({held})"
            if ok
            else f"door opened to {angle:.1f} deg of {goal:.0f}, {held}"
        )
        return outcome, _prefix(outcome, text), {"door_max_deg": angle, "success": float(ok)}
    if macro == Macro.SURFACE_SCAN:
        pct = 100.0 * v.coverage
        text = f"covered {pct:.0f} % of the surface (goal {100 * COVERAGE_GOAL:.0f} %)"
        return outcome, _prefix(outcome, text), {"coverage": v.coverage, "success": float(ok)}
    if macro == Macro.FOLLOW_PERIMETER:
        dev = v.perimeter_max_dev_m * 1e3
        pct = 100.0 * v.perimeter_passed
        text = (
            f"passed {pct:.0f} % of the outline, at most {dev:.1f} mm off it (goal "
            f"{100 * COVERAGE_GOAL:.0f} % within {PERIMETER_TOLERANCE_M * 1e3:.0f} mm)"
        )
        figures = {"perimeter_passed": v.perimeter_passed, "perimeter_max_dev_mm": dev}
        return outcome, _prefix(outcome, text), {**figures, "success": float(ok)}
    if macro == Macro.PLACE_DEVICE:
        if not np.isfinite(v.device_error_m):
            missed = "missed: the device was not released near its spot"
            return Outcome.MISSED, missed, {"success": 0.0}
        err = v.device_error_m * 1e3
        text = (
            f"device released {err:.1f} mm from its spot "
            f"(tolerance {DEVICE_TOLERANCE_M * 1e3:.0f} mm)"
        )
        return outcome, _prefix(outcome, text), {"device_error_mm": err, "success": float(ok)}
    return Outcome.DONE, f"done: {macro} played to its end (the world does not judge it)", {}


def _grasp(outcome: Outcome, v: Verdicts) -> tuple[Outcome, str, dict[str, float]]:
    """A grasp macro's words; ``outcome`` is the judge's (a grasp macro's target is the pipe:
    a grab that caught the door's handle instead is a miss of it, said with what it caught)."""
    if not np.isfinite(v.grasp_distance_m):
        if v.handle_held and np.isfinite(v.handle_distance_m):
            mm = v.handle_distance_m * 1e3
            text = (
                f"the gripper caught the door's handle, {mm:.1f} mm off its axis, not the pipe "
                "(Move Around Axis opens the door with it)"
            )
            figures = {"handle_distance_mm": mm, "success": float(outcome == Outcome.SUCCEEDED)}
            return outcome, _prefix(outcome, text), figures
        if np.isfinite(v.closed_distance_m):
            text = f"missed: gripper closed {v.closed_distance_m * 1e3:.0f} mm off the pipe axis"
            return (
                Outcome.MISSED,
                text,
                {"grasp_distance_mm": v.closed_distance_m * 1e3, "success": 0.0},
            )
        return Outcome.MISSED, "missed: the gripper never closed", {"success": 0.0}
    mm = v.grasp_distance_m * 1e3
    deg = math.degrees(v.grasp_angle_rad)
    figures = {
        "grasp_distance_mm": mm,
        "grasp_angle_deg": deg,
        "success": float(outcome == Outcome.SUCCEEDED),
    }
    if outcome == Outcome.SUCCEEDED:
        return outcome, f"grasped: {mm:.1f} mm off the pipe axis, {deg:.1f} deg off it", figures
    where = "" if v.grasp_inside else ", past the pipe's end"
    text = (
        f"missed: gripper closed {mm:.1f} mm off the pipe axis, {deg:.1f} deg off it{where} "
        f"(tolerance {GRASP_TOLERANCE_M * 1e3:.0f} mm, "
        f"{math.degrees(GRASP_TOLERANCE_RAD):.0f} deg)"
    )
    return outcome, text, figures


def _prefix(outcome: Outcome, text: str) -> str:
    return f"{outcome}: {text}"
