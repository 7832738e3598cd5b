"""Numeric inverse kinematics of a DH arm: damped Gauss-Newton on the pose error.

Used to place the simulated arm (camera above the expected tool) and by the open-loop baseline
grab. Pose error: translation [m] and the rotation vector of R_target R_current^T [rad], both in
base coordinates; the geometric Jacobian maps joint steps to exactly that error to first order.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.arm.dh import DHTable
from umbra.modules.arm.jacobian import jacobian_and_pose

FloatArray = NDArray[np.float64]


class IKFailed(ValueError):
    """No joint values within the limits reach the target pose."""


def pose_error(T_target: FloatArray, T_current: FloatArray) -> FloatArray:
    """``[dp; dtheta]`` (m, rad), base coordinates, that moves ``T_current`` onto ``T_target``."""
    from scipy.spatial.transform import Rotation  # lazy: tests/runtime/test_start_imports.py

    dp = T_target[:3, 3] - T_current[:3, 3]
    dtheta = Rotation.from_matrix(T_target[:3, :3] @ T_current[:3, :3].T).as_rotvec()
    return np.concatenate([dp, dtheta])


def wrap_into_limits(table: DHTable, q: FloatArray) -> FloatArray:
    """Shift revolute joints by whole turns so they fall inside their limits where they can."""
    q = q.copy()
    for i in np.flatnonzero(table.revolute):
        centre = 0.5 * (table.q_min[i] + table.q_max[i])
        q[i] = centre + (q[i] - centre + np.pi) % (2 * np.pi) - np.pi
        for shift in (-2 * np.pi, 2 * np.pi):
            if (
                not table.q_min[i] <= q[i] <= table.q_max[i]
                and table.q_min[i] <= q[i] + shift <= table.q_max[i]
            ):
                q[i] += shift
    return q


def solve_ik(
    table: DHTable,
    T_base_target: ArrayLike,
    q_seed: ArrayLike,
    T_flange_tool: ArrayLike | None = None,
    *,
    tolerance: float = 1e-9,
    max_iterations: int = 200,
    damping: float = 1e-3,
) -> FloatArray:
    """Joint values putting the tool frame at ``T_base_target``, starting from ``q_seed``.

    Raises IKFailed when the error does not fall below ``tolerance`` (norm, m and rad mixed) or
    the solution leaves the joint limits.
    """
    target = np.asarray(T_base_target, dtype=float)
    q = table.check_q(q_seed).copy()
    err = np.full(6, np.inf)
    for _ in range(max_iterations):
        J, T = jacobian_and_pose(table, q, T_flange_tool)
        err = pose_error(target, T)
        if float(np.linalg.norm(err)) < tolerance:
            break
        step = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(6), err)
        q = q + step
    else:
        raise IKFailed(
            f"no IK solution: pose error {np.linalg.norm(err):.3g} after "
            f"{max_iterations} iterations"
        )
    q = wrap_into_limits(table, q)
    if np.any(q < table.q_min) or np.any(q > table.q_max):
        raise IKFailed(
            f"IK solution {np.round(np.degrees(q), 1).tolist()} deg is outside the joint limits"
        )
    return q
