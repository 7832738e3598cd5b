"""The macro menu by primitive (LDRD report section 3) and each macro's key tool poses.

A macro turns a primitive (or nothing) and the arm's current tool pose into key poses
``T_base_tool`` with a gripper opening at each (1 open, 0 closed), or into joint targets for the
canned motions. :mod:`umbra.modules.sketch.path_check` then samples, solves and checks the path.
Conventions of :mod:`umbra.modules.sketch.tool_poses` (tool z = approach, x = across the fingers).
Options (``MacroRequest.options``) override the defaults named in each description.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.sketch_messages import Macro, SketchPrimitive
from umbra.modules.sketch.primitives import line_axis, plane_rect, point_of
from umbra.modules.sketch.tool_poses import DOWN, arc, rotate_about_axis, tool_pose

FloatArray = NDArray[np.float64]

#: kind of primitive ("none" = nothing selected) -> [(macro, what it does)]
MENU: dict[str, list[tuple[Macro, str]]] = {
    "none": [
        (Macro.READY, "joints to the ready pose (tool above the table, looking down)"),
        (Macro.STOW, "joints to the stowed pose"),
    ],
    "point": [
        (Macro.MOVE_TO, "tool point to `standoff` (0.05 m) above the point, looking down"),
        (
            Macro.AIM_ALONG_RAY,
            "tool axis along camera a's ray, `standoff` (0.15 m) before the point",
        ),
    ],
    "line": [
        (Macro.GRAB_PIPE, "grasp the line's middle from above, fingers across the axis"),
        (Macro.MOVE_AROUND_AXIS, "sweep `angle_deg` (85) about the line, right-hand rule"),
        (
            Macro.APPROACH_SIDE,
            "grasp the middle from the arm's side, `elevation_deg` (20) below level",
        ),
        (Macro.MOVE_PARALLEL, "move the tool along the line by its length x `fraction` (1)"),
        (Macro.AIM_ALONG_AXIS, "tool axis along the line, `standoff` (0.1 m) before its start"),
        (Macro.PLACE_DEVICE, "set the held device `standoff` (0.08 m) in front of the edge"),
    ],
    "plane": [
        (Macro.SURFACE_SCAN, "raster the rectangle at `standoff` (0.08 m), `spacing` (0.028 m)"),
        (Macro.FOLLOW_PERIMETER, "follow the rectangle's outline at `standoff` (0.08 m)"),
    ],
    "triad": [(Macro.MAKE_BOX, "keep the box as scene geometry (no motion)")],
}


def macro_named(name: str) -> Macro:
    """The macro called ``name`` (a person's or a file's word); raises MacroError naming the
    macros there are."""
    return Macro.named(name, "there is no macro", MacroError)


def macro_label(macro: str) -> str:
    """The macro's name for a person ("grab_pipe" -> "Grab pipe")."""
    return macro.replace("_", " ").capitalize()


#: the options each macro takes: name -> (lowest, highest) accepted value (m, deg or 1)
OPTIONS: dict[Macro, dict[str, tuple[float, float]]] = {
    Macro.MOVE_TO: {"standoff": (0.0, 0.5)},
    Macro.AIM_ALONG_RAY: {"standoff": (0.0, 0.5)},
    Macro.APPROACH_SIDE: {"elevation_deg": (0.0, 60.0)},
    Macro.MOVE_AROUND_AXIS: {"angle_deg": (-180.0, 180.0)},
    Macro.MOVE_PARALLEL: {"fraction": (-2.0, 2.0)},
    Macro.AIM_ALONG_AXIS: {"standoff": (0.0, 0.5)},
    Macro.PLACE_DEVICE: {"standoff": (0.0, 0.5)},
    Macro.SURFACE_SCAN: {"standoff": (0.02, 0.5), "spacing": (0.005, 0.2)},
    Macro.FOLLOW_PERIMETER: {"standoff": (0.02, 0.5)},
}

PREGRASP_M = 0.10
DEVICE_HALF_HEIGHT_M = 0.03


class MacroError(ValueError):
    """A macro that does not apply (wrong primitive, missing input)."""


@dataclass
class MacroKeys:
    """Key poses (or joint targets) of a macro, with the gripper opening at each and the point the
    cameras should watch (m, base)."""

    macro: Macro
    poses: list[FloatArray] = field(default_factory=list)
    gripper: list[float] = field(default_factory=list)
    joint_targets: list[FloatArray] = field(default_factory=list)
    watch: FloatArray | None = None
    sweep: tuple[FloatArray, FloatArray, float] | None = None  #: (point, direction, angle)


def menu_for(primitive: SketchPrimitive | None) -> list[tuple[Macro, str]]:
    """The macros a primitive (None: nothing selected) makes available."""
    return MENU["none" if primitive is None else primitive.kind]


def check_options(macro: Macro, options: dict[str, float] | None) -> dict[str, float]:
    """The options of ``macro`` as floats; raises MacroError for an option the macro does not
    take, or a value that is not a finite number within its range (see :data:`OPTIONS`)."""
    allowed = OPTIONS.get(macro, {})
    out: dict[str, float] = {}
    for key, value in (options or {}).items():
        if key not in allowed:
            expected = ", ".join(allowed) if allowed else "none"
            raise MacroError(f"macro '{macro}' has no option {key!r}; its options: {expected}")
        low, high = allowed[key]
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = float("nan")
        if not (np.isfinite(number) and low <= number <= high):
            raise MacroError(
                f"macro '{macro}': option {key} must be a number within {low:g} .. {high:g}, "
                f"got {value!r}"
            )
        out[key] = number
    return out


def macro_keys(
    macro: Macro,
    primitive: SketchPrimitive | None,
    T_tool: FloatArray,
    gripper: float,
    options: dict[str, float] | None = None,
    *,
    q_ready: FloatArray | None = None,
    q_stow: FloatArray | None = None,
    camera_centre: FloatArray | None = None,
) -> MacroKeys:
    """Key poses of ``macro`` for ``primitive`` from the current tool pose ``T_tool``.

    ``make_box`` has no motion: its keys are empty (the caller keeps the triad's box)."""
    names = [m for m, _ in menu_for(primitive)]
    if macro not in names:
        kind = "nothing selected" if primitive is None else f"a {primitive.kind}"
        raise MacroError(
            f"macro '{macro}' is not on the menu for {kind}; expected one of {', '.join(names)}"
        )
    opts = check_options(macro, options)
    keys = MacroKeys(macro)
    if macro in (Macro.READY, Macro.STOW):
        target = q_ready if macro == Macro.READY else q_stow
        if target is None:
            raise MacroError(f"no {macro} pose configured")
        keys.joint_targets = [np.asarray(target, dtype=float)]
        keys.gripper = [gripper]
        return keys
    if macro == Macro.MAKE_BOX:
        return keys
    assert primitive is not None
    x_hint = T_tool[:3, 0]
    if macro == Macro.MOVE_TO:
        p = point_of(primitive)
        keys.poses = [
            tool_pose(p + np.array([0.0, 0.0, opts.get("standoff", 0.05)]), DOWN, x_hint, x_hint)
        ]
        keys.gripper, keys.watch = [gripper], p
    elif macro == Macro.AIM_ALONG_RAY:
        if camera_centre is None:
            raise MacroError("aim_along_ray needs camera a's centre")
        p = point_of(primitive)
        ray = (p - camera_centre) / np.linalg.norm(p - camera_centre)
        pose = tool_pose(p - opts.get("standoff", 0.15) * ray, ray, x_hint, x_hint)
        keys.poses, keys.gripper, keys.watch = [pose], [gripper], p
    elif macro in (Macro.GRAB_PIPE, Macro.APPROACH_SIDE):
        axis = line_axis(primitive)
        m = axis.middle
        if macro == Macro.GRAB_PIPE:
            approach = DOWN
        else:
            outward = m.copy()
            outward[2] = 0.0
            level = outward - (outward @ axis.direction) * axis.direction
            level[2] = 0.0
            if np.linalg.norm(level) < 1e-6:
                raise MacroError("approach_side: the line points at the arm; no side faces it")
            level /= np.linalg.norm(level)
            # tilted down below level: a horizontal approach at the table puts the Puma's wrist
            # at its limit
            dip = np.radians(opts.get("elevation_deg", 20.0))
            approach = np.cos(dip) * level + np.sin(dip) * DOWN
        grasp = tool_pose(m, approach, axis.direction, x_hint)
        pre = grasp.copy()
        pre[:3, 3] = m - PREGRASP_M * approach
        keys.poses, keys.gripper, keys.watch = [pre, grasp], [1.0, 0.0], m
    elif macro == Macro.MOVE_AROUND_AXIS:
        axis = line_axis(primitive)
        angle = float(np.radians(opts.get("angle_deg", 85.0)))
        keys.poses = list(arc(T_tool, axis.start, axis.direction, angle, np.radians(1.0))[1:])
        keys.gripper = [0.0] * len(keys.poses)
        keys.sweep = (axis.start, axis.direction, angle)
        keys.watch = rotate_about_axis(T_tool, axis.start, axis.direction, angle / 2)[:3, 3]
    elif macro == Macro.MOVE_PARALLEL:
        axis = line_axis(primitive)
        pose = T_tool.copy()
        pose[:3, 3] += opts.get("fraction", 1.0) * (axis.end - axis.start)
        keys.poses, keys.gripper, keys.watch = [pose], [gripper], pose[:3, 3]
    elif macro == Macro.AIM_ALONG_AXIS:
        axis = line_axis(primitive)
        pose = tool_pose(
            axis.start - opts.get("standoff", 0.1) * axis.direction,
            axis.direction,
            x_hint if abs(x_hint @ axis.direction) < 0.9 else T_tool[:3, 1],
            x_hint,
        )
        keys.poses, keys.gripper, keys.watch = [pose], [gripper], axis.start
    elif macro == Macro.PLACE_DEVICE:
        axis = line_axis(primitive)
        m = axis.middle
        outward = np.array([-m[0], -m[1], 0.0])  # towards the arm's base
        outward -= (outward @ axis.direction) * axis.direction
        outward[2] = 0.0
        outward /= np.linalg.norm(outward)
        spot = m + opts.get("standoff", 0.08) * outward + [0.0, 0.0, DEVICE_HALF_HEIGHT_M]
        place = tool_pose(spot, DOWN, axis.direction, x_hint)
        above = place.copy()
        above[2, 3] += PREGRASP_M
        keys.poses, keys.gripper, keys.watch = [above, place], [gripper, 1.0], spot
    elif macro in (Macro.SURFACE_SCAN, Macro.FOLLOW_PERIMETER):
        rect = plane_rect(primitive)
        normal = rect.normal if rect.normal[2] >= 0 else -rect.normal
        standoff = opts.get("standoff", 0.08)
        if macro == Macro.SURFACE_SCAN:
            points = _raster(rect.corner, rect.edge_u, rect.edge_v, opts.get("spacing", 0.028))
        else:
            corners = rect.perimeter()
            points = np.concatenate([corners, corners[:1]])
        across = rect.edge_u
        up = points + standoff * normal
        poses = [tool_pose(p, -normal, across, x_hint) for p in up]
        lead = poses[0].copy()
        lead[:3, 3] += 0.05 * normal
        keys.poses = [lead, *poses]
        keys.gripper = [gripper] * len(keys.poses)
        keys.watch = rect.corner + 0.5 * (rect.edge_u + rect.edge_v)
    return keys


def _raster(corner: FloatArray, edge_u: FloatArray, edge_v: FloatArray, spacing: float):
    """Boustrophedon points over the parallelogram: lines along ``edge_u``, ``spacing`` apart
    across it, inset by 0.012 m across and 0.004 m along."""
    lu, lv = float(np.linalg.norm(edge_u)), float(np.linalg.norm(edge_v))
    u, v = edge_u / lu, edge_v / lv
    inset = min(0.012, lv / 2)
    n = max(1, int(np.ceil((lv - 2 * inset) / spacing)))
    rows = np.linspace(inset, lv - inset, n + 1)
    points = []
    for i, b in enumerate(rows):
        ends = [0.004, lu - 0.004]
        if i % 2:
            ends.reverse()
        points += [corner + ends[0] * u + b * v, corner + ends[1] * u + b * v]
    return np.stack(points)
