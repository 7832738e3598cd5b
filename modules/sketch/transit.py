"""A joint-space transit to a macro's first key pose, for when the straight Cartesian way there
is refused (a wrist that must turn over, a branch jump).

A macro's first segment (from wherever the tool is to its first key pose: a pre-grasp, a
standoff) needs no straight tool line; only the segments after it do (the approach, the scan).
When the Cartesian plan of the whole macro is refused, the planner tries this: solve the first
key pose from several seeds, and move the joints there in joint space, either all together or
staged (every joint but one first, then that one: a wrist bend that changes sign crosses its
singularity alone, so no joint rate is asked along the singular direction).

Moving through a singular configuration in joint space is fine for the arm, but the player
commands it as a tool twist that the resolved-rate kinematics (damped least squares) turns back
into joint rates; :func:`twist_round_trip_error` measures how well a joint motion survives that
round trip, and a transit is accepted only where it does. Radians, metres.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.dls import DLSSettings, solve_dls
from umbra.modules.arm.jacobian import jacobian_and_pose
from umbra.modules.world.ik import IKFailed, solve_ik

FloatArray = NDArray[np.float64]

#: the resolved-rate kinematics' damping (WOLVERINE_KIN's defaults)
KINEMATICS_DLS = DLSSettings(eps=0.04, lambda_max=0.04)
SEEDS = 40


def twist_round_trip_error(
    table: DHTable, T_flange_tool: FloatArray, q: FloatArray, direction: FloatArray
) -> float:
    """Relative error (1) of the joint direction ``direction`` after tool twist -> DLS joint
    rates at ``q``: 0 where the kinematics gives back exactly the commanded joint motion."""
    norm = float(np.linalg.norm(direction))
    if norm < 1e-12:
        return 0.0
    d = direction / norm
    J, _ = jacobian_and_pose(table, q, T_flange_tool)
    back = solve_dls(
        J, J @ d, q, table.q_min, table.q_max, np.full(table.n, 1e9), KINEMATICS_DLS
    ).rates
    return float(np.linalg.norm(back - d))


def goal_candidates(
    table: DHTable,
    T_goal: FloatArray,
    q_now: FloatArray,
    T_flange_tool: FloatArray,
    margin: float,
) -> list[FloatArray]:
    """Distinct joint solutions of ``T_goal`` within the limits by ``margin`` (rad), nearest
    ``q_now`` first; seeds: ``q_now`` and a fixed pseudo-random spread (deterministic)."""
    rng = np.random.default_rng(0)
    low, high = table.q_min + margin, table.q_max - margin
    seeds = [q_now] + [rng.uniform(low, high) for _ in range(SEEDS)]
    found: list[FloatArray] = []
    for seed in seeds:
        try:
            q = solve_ik(table, T_goal, seed, T_flange_tool, tolerance=1e-9, max_iterations=100)
        except IKFailed:
            continue
        if np.any(q < low) or np.any(q > high):
            continue
        if all(np.max(np.abs(q - other)) > 1e-3 for other in found):
            found.append(q)
    return sorted(found, key=lambda q: float(np.max(np.abs(q - q_now))))


def transit_options(q_now: FloatArray, q_goal: FloatArray, step: float) -> list[FloatArray]:
    """Joint samples from ``q_now`` to ``q_goal`` (at most ``step`` rad apart): all joints
    together, then staged with each joint in turn moved last (the last joint first)."""
    options = [_line([q_now, q_goal], step)]
    for k in reversed(range(q_now.size)):
        if abs(q_goal[k] - q_now[k]) < 1e-9:
            continue
        middle = q_goal.copy()
        middle[k] = q_now[k]
        options.append(_line([q_now, middle, q_goal], step))
    return options


def transit_problem(
    table: DHTable,
    T_flange_tool: FloatArray,
    joints: FloatArray,
    margin: float,
    max_error: float,
) -> str:
    """Why a transit cannot be commanded ("" when it can): a joint within ``margin`` of a limit,
    or a sample whose motion loses more than ``max_error`` in the twist round trip."""
    if any(np.min(table.limit_margin(q)) < margin for q in joints):
        return "joint limits"
    for i in range(len(joints) - 1):
        error = twist_round_trip_error(table, T_flange_tool, joints[i], joints[i + 1] - joints[i])
        if error > max_error:
            return f"the kinematics cannot follow it at sample {i} (round-trip error {error:.2f})"
    return ""


def _line(points: list[FloatArray], step: float) -> FloatArray:
    out = [points[0]]
    for a, b in itertools.pairwise(points):
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))
        out += [a + (b - a) * i / n for i in range(1, n + 1)]
    return np.stack(out)
