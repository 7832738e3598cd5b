"""Geometric Jacobian of a DH arm in its base frame, and manipulability.

``J(q)`` is ``6 x n`` with rows ``[v; w]``: ``v`` the linear velocity (m/s) of the tool point
(the flange origin when no tool is given) and ``w`` the angular velocity (rad/s), both with
base-frame coordinates, for unit joint rates. Column ``i`` of a revolute joint is
``[z_{i-1} x (p - o_{i-1}); z_{i-1}]``, of a prismatic joint ``[z_{i-1}; 0]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from umbra.modules.arm.dh import DHTable
from umbra.modules.geometry.transforms import cross3

FloatArray = NDArray[np.float64]


def jacobian_and_pose(
    table: DHTable, q: ArrayLike, T_flange_tool: ArrayLike | None = None
) -> tuple[FloatArray, FloatArray]:
    """``(J, T_base_tool)``: the base-frame geometric Jacobian at the tool point and its pose.

    One pass over the chain gives both; ``T_base_tool`` is ``T_base_flange`` without a tool.
    """
    return jacobian_and_pose_at_frames(table, table.frames(q), T_flange_tool)


def jacobian_and_pose_at_frames(
    table: DHTable, T: FloatArray, T_flange_tool: ArrayLike | None = None
) -> tuple[FloatArray, FloatArray]:
    """As :func:`jacobian_and_pose`, from the DH frames ``T`` (``(n + 1, 4, 4)``, ``T_base_i``
    for ``i = 0 .. n``, :meth:`DHTable.frames`) when the caller needs them too."""
    T_end = T[-1] if T_flange_tool is None else T[-1] @ np.asarray(T_flange_tool, dtype=float)
    z = T[:-1, :3, 2]  # (n, 3) joint axes z_{i-1}
    o = T[:-1, :3, 3]  # (n, 3) origins o_{i-1}
    J = np.empty((6, table.n))
    revolute = table.revolute
    J[:3] = np.where(revolute[:, None], cross3(z, T_end[:3, 3] - o), z).T
    J[3:] = np.where(revolute[:, None], z, 0.0).T
    return J, T_end


def jacobian(table: DHTable, q: ArrayLike, T_flange_tool: ArrayLike | None = None) -> FloatArray:
    """Geometric Jacobian ``6 x n`` in the base frame, rows ``[v; w]``, at the tool point."""
    return jacobian_and_pose(table, q, T_flange_tool)[0]


def manipulability(J: ArrayLike) -> float:
    """Yoshikawa's manipulability ``sqrt(det(J J^T))`` (the product of J's singular values).

    Mixed units (metres and radians) as in the Jacobian; zero at a singularity.
    """
    J = np.asarray(J, dtype=float)
    return float(np.prod(np.linalg.svd(J, compute_uv=False)))


def tool_twist_in_base(T_base_tool: ArrayLike, tool_twist: ArrayLike) -> FloatArray:
    """Re-express a tool-frame twist ``[v; w]`` (tool point, tool coordinates) in base coordinates.

    Same point, new coordinates: ``[R v; R w]`` with ``R`` the rotation of ``T_base_tool``. This is
    what the base-frame Jacobian at the tool point expects.
    """
    R = np.asarray(T_base_tool, dtype=float)[:3, :3]
    xi = np.asarray(tool_twist, dtype=float).reshape(6)
    return np.concatenate([R @ xi[:3], R @ xi[3:]])
