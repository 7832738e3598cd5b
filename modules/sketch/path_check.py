"""From a macro's key poses to a checked joint path (:class:`ToolPath`), before anything moves.

The key poses are sampled densely (:func:`umbra.modules.sketch.tool_poses.interpolate`), each sample
is solved for the joints starting from the previous one (damped Gauss-Newton,
:func:`umbra.modules.world.ik.solve_ik`), and the path is refused, with the reason, when:

* reach: a sample has no IK solution (or the solution jumps to another branch: a joint step
  larger than ``max_joint_step`` between neighbouring samples);
* joint limits: a joint comes closer than ``limit_margin`` to a limit;
* singularities: the Jacobian's smallest singular value drops below ``min_sigma``;
* speed: the timing that keeps every joint within ``rate_fraction`` of its rate limit and the
  tool within ``max_linear`` / ``max_angular`` (the guard's clamps) would be slower than
  ``min_rate``.

When the straight Cartesian way to the macro's first key pose is refused, a joint-space transit
there is tried (:mod:`umbra.modules.sketch.transit`); its samples are checked for what matters for a
joint motion (limits, and that the twist interface can command it) instead of the Jacobian's
smallest singular value; the segments after the first key stay straight tool lines.

The path parameter ``s`` is the joint-space arc length (rad, Euclidean); the nominal playing
rate ``checks["rate"]`` (rad/s of s) is the largest that respects every speed limit.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from umbra.connectors.path_messages import ToolPath
from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.jacobian import jacobian_and_pose
from umbra.modules.sketch.macros import MacroKeys
from umbra.modules.sketch.tool_poses import interpolate
from umbra.modules.sketch.transit import goal_candidates, transit_options, transit_problem
from umbra.modules.world.ik import IKFailed, solve_ik

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PathLimits:
    """Thresholds of the plan checks (rad, m, s)."""

    limit_margin: float = np.radians(3.0)
    min_sigma: float = 0.02
    rate_fraction: float = 0.5
    max_linear: float = 0.08
    max_angular: float = 0.4
    min_rate: float = 0.01
    max_joint_step: float = 0.15
    step_m: float = 0.005
    step_rad: float = np.radians(2.0)


def plan_path(
    keys: MacroKeys,
    table: DHTable,
    T_flange_tool: FloatArray,
    q_now: FloatArray,
    gripper_now: float,
    limits: PathLimits,
    *,
    path_id: str,
    stamp: float = 0.0,
) -> ToolPath:
    """The checked path of ``keys`` from the arm's joints ``q_now``; ``ok`` False with a reason
    when a check fails (the samples up to the failure are kept for display)."""
    q_now = np.asarray(q_now, dtype=float)
    T_now = table.fk(q_now, T_flange_tool)
    transit = 0
    if keys.joint_targets:
        joints = _joint_line(q_now, keys.joint_targets, limits.step_rad)
        poses = np.stack([table.fk(q, T_flange_tool) for q in joints])
        gripper = np.full(len(joints), gripper_now)
        reason = ""
    else:
        poses, key_index = interpolate([T_now, *keys.poses], limits.step_m, limits.step_rad)
        grip_keys = [gripper_now, *keys.gripper]
        # a sample inside a segment keeps the opening of the key it left; the segment's last
        # sample (the key reached) takes that key's opening
        gripper = np.array([grip_keys[k] for k in key_index])
        joints, reason = _solve(poses, table, T_flange_tool, q_now, limits)
    checks: dict[str, float] = {"samples": float(len(joints))}
    if not reason:
        reason = _check(joints, poses[: len(joints)], table, T_flange_tool, limits, checks)
    if reason and keys.poses:
        other = _with_transit(keys, table, T_flange_tool, q_now, gripper_now, limits)
        if other is not None:
            joints, poses, gripper, transit = other
            checks = {"samples": float(len(joints)), "transit_samples": float(transit)}
            reason = _check(joints, poses, table, T_flange_tool, limits, checks, transit)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(joints, axis=0), axis=1))])
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    n = len(joints)
    return ToolPath(
        stamp=stamp,
        path_id=path_id,
        macro=keys.macro,
        names=table.names,
        s=s[keep],
        joints=joints[keep],
        T_base_tool=poses[:n][keep],
        gripper=np.asarray(gripper[:n], dtype=float)[keep],
        ok=bool(not reason and n >= 2 and s[-1] > 1e-6),
        reason=reason or ("" if n >= 2 and s[-1] > 1e-6 else "the path has no length"),
        checks={k: float(v) for k, v in checks.items()},
    )


def _with_transit(keys: MacroKeys, table, T_flange_tool, q_now, gripper_now, limits):
    """(joints, poses, gripper, transit samples) of the macro with a joint-space transit to its
    first key pose, or None when no transit and straight rest pass (see module docstring)."""
    rest, rest_index = interpolate(keys.poses, limits.step_m, limits.step_rad)
    for q_goal in goal_candidates(table, keys.poses[0], q_now, T_flange_tool, limits.limit_margin):
        rest_joints, why = _solve(rest, table, T_flange_tool, q_goal, limits)
        if why:
            continue
        for moves in transit_options(q_now, q_goal, limits.step_rad):
            if transit_problem(table, T_flange_tool, moves, limits.limit_margin, 0.1):
                continue
            joints = np.concatenate([moves, rest_joints[1:]])
            poses = np.stack([table.fk(q, T_flange_tool) for q in moves] + list(rest[1:]))
            gripper = [gripper_now] * (len(moves) - 1) + [keys.gripper[0]]
            gripper += [keys.gripper[k] for k in rest_index[1:]]
            return joints, poses, np.asarray(gripper, dtype=float), len(moves) - 1
    return None


def _joint_line(q0: FloatArray, targets: list[FloatArray], step: float) -> FloatArray:
    points = [q0]
    for target in targets:
        a = points[-1]
        n = max(1, int(np.ceil(np.max(np.abs(target - a)) / step)))
        points += [a + (target - a) * i / n for i in range(1, n + 1)]
    return np.stack(points)


def _solve(poses, table, T_flange_tool, q0, limits: PathLimits) -> tuple[FloatArray, str]:
    joints = [q0]
    for i, T in enumerate(poses[1:], start=1):
        try:
            q = solve_ik(table, T, joints[-1], T_flange_tool, tolerance=1e-8, max_iterations=100)
        except IKFailed as exc:
            p = np.round(T[:3, 3], 3).tolist()
            return np.stack(joints), f"reach: sample {i} of {len(poses)} at {p} m: {exc}"
        q = _nearest_turn(table, q, joints[-1])
        jump = float(np.max(np.abs(q - joints[-1])))
        if jump > limits.max_joint_step:
            p = np.round(T[:3, 3], 3).tolist()
            return np.stack(joints), (
                f"reach: the joints jump {np.degrees(jump):.1f} deg between samples {i - 1} and "
                f"{i} at {p} m (another arm configuration); expected at most "
                f"{np.degrees(limits.max_joint_step):.1f} deg"
            )
        joints.append(q)
    return np.stack(joints), ""


def _nearest_turn(table: DHTable, q: FloatArray, q_prev: FloatArray) -> FloatArray:
    """``q`` with each revolute joint shifted by whole turns towards ``q_prev`` where the shifted
    value stays within the limits (IK may return any of them)."""
    out = q.copy()
    for i in np.flatnonzero(table.revolute):
        shifted = q[i] + 2 * np.pi * np.round((q_prev[i] - q[i]) / (2 * np.pi))
        if table.q_min[i] <= shifted <= table.q_max[i]:
            out[i] = shifted
    return out


def _check(
    joints, poses, table: DHTable, T_flange_tool, limits: PathLimits, checks, transit: int = 0
) -> str:
    """The checks of the module docstring; the first ``transit`` samples are a joint transit
    (already checked by :func:`transit_problem`) and skip the singular-value check."""
    from scipy.spatial.transform import Rotation

    margins = np.array([table.limit_margin(q) for q in joints])
    worst = np.unravel_index(np.argmin(margins), margins.shape)
    checks["min_limit_margin_deg"] = float(np.degrees(margins[worst]))
    if margins[worst] < limits.limit_margin:
        return (
            f"joint limits: {table.names[worst[1]]} comes within "
            f"{np.degrees(margins[worst]):.1f} deg of its limit at sample {worst[0]}; expected a "
            f"margin of at least {np.degrees(limits.limit_margin):.1f} deg"
        )
    sigmas = np.array(
        [
            np.linalg.svd(jacobian_and_pose(table, q, T_flange_tool)[0], compute_uv=False)[-1]
            for q in joints
        ]
    )
    sigmas[:transit] = np.inf
    checks["min_sigma"] = float(sigmas.min())
    if sigmas.min() < limits.min_sigma:
        i = int(np.argmin(sigmas))
        return (
            f"singularity: the Jacobian's smallest singular value is {sigmas[i]:.4f} at sample "
            f"{i} ({np.round(poses[i][:3, 3], 3).tolist()} m); expected at least "
            f"{limits.min_sigma}"
        )
    ds = np.linalg.norm(np.diff(joints, axis=0), axis=1)
    moving = ds > 1e-9
    if not np.any(moving):
        checks["rate"] = 0.0
        return ""
    dq = np.abs(np.diff(joints, axis=0))[moving] / ds[moving, None]
    dp = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)[moving] / ds[moving]
    rel = [
        Rotation.from_matrix(b[:3, :3] @ a[:3, :3].T).magnitude()
        for a, b in itertools.pairwise(poses)
    ]
    dr = np.asarray(rel)[moving] / ds[moving]
    qd_max = np.asarray(table.qd_max) * limits.rate_fraction
    bounds = [float(np.min(qd_max / np.maximum(dq.max(axis=0), 1e-12)))]
    bounds.append(limits.max_linear / max(float(dp.max()), 1e-12))
    bounds.append(limits.max_angular / max(float(dr.max()), 1e-12))
    rate = min(bounds)
    checks["rate"] = rate
    checks["peak_tool_speed"] = float(dp.max() * rate)
    checks["peak_tool_turn_rate"] = float(dr.max() * rate)
    checks["length"] = float(ds.sum())
    checks["duration"] = float(ds.sum() / rate)
    if rate < limits.min_rate:
        which = ["joint rates", "tool speed", "tool turn rate"][int(np.argmin(bounds))]
        return (
            f"speed: the {which} limit allows only {rate:.4f} rad/s along the path; expected at "
            f"least {limits.min_rate}"
        )
    return ""
