"""Tool poses for macros, and dense Cartesian paths between key poses.

Tool frame convention (shared with the world's judge): z = approach direction (out of the
gripper), y = the fingers' closing direction, x = across the fingers (along a grasped bar).
Poses are ``T_base_tool`` (4 x 4, m). Between key poses the tool point moves on a straight line
and the orientation by the shortest rotation (slerp), sampled at most ``step_m`` / ``step_rad``
apart.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
DOWN = np.array([0.0, 0.0, -1.0])


def tool_pose(
    point: ArrayLike, approach: ArrayLike, across: ArrayLike, x_hint: ArrayLike | None = None
) -> FloatArray:
    """The tool at ``point`` with z along ``approach`` and x along ``across`` (made orthogonal to
    the approach); x's sign is chosen to agree with ``x_hint`` (the current tool x) so that the
    wrist does not turn half a revolution for a symmetric grasp."""
    approach_v = np.asarray(approach, dtype=float)
    across_v = np.asarray(across, dtype=float)
    z = approach_v / np.linalg.norm(approach_v)
    x = across_v - (across_v @ z) * z
    if np.linalg.norm(x) < 1e-6:
        raise ValueError(f"the grasp axis {across_v} is parallel to the approach {approach_v}")
    x = x / np.linalg.norm(x)
    if x_hint is not None and x @ np.asarray(x_hint, dtype=float) < 0:
        x = -x
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = np.asarray(point, dtype=float)
    return T


def rotate_about_axis(T: FloatArray, point: ArrayLike, direction: ArrayLike, angle: float):
    """``T`` turned by ``angle`` (rad, right-hand rule) about the line through ``point`` along
    ``direction``."""
    from scipy.spatial.transform import Rotation

    u = np.asarray(direction, dtype=float)
    R = Rotation.from_rotvec(angle * u / np.linalg.norm(u)).as_matrix()
    c = np.asarray(point, dtype=float)
    out = np.eye(4)
    out[:3, :3] = R @ T[:3, :3]
    out[:3, 3] = R @ (T[:3, 3] - c) + c
    return out


def interpolate(
    keys: list[FloatArray], step_m: float = 0.005, step_rad: float = np.radians(2.0)
) -> tuple[FloatArray, FloatArray]:
    """Dense poses through key poses (straight lines, slerp) and, per sample, the index of the key
    segment it belongs to (the key itself for the last sample of a segment)."""
    from scipy.spatial.transform import Rotation, Slerp

    poses = [keys[0]]
    key_index = [0]
    for k in range(1, len(keys)):
        a, b = keys[k - 1], keys[k]
        dist = float(np.linalg.norm(b[:3, 3] - a[:3, 3]))
        turn = float(Rotation.from_matrix(b[:3, :3] @ a[:3, :3].T).magnitude())
        n = max(1, int(np.ceil(max(dist / step_m, turn / step_rad))))
        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([a[:3, :3], b[:3, :3]])))
        for i in range(1, n + 1):
            t = i / n
            T = np.eye(4)
            T[:3, :3] = slerp([t]).as_matrix()[0]
            T[:3, 3] = (1 - t) * a[:3, 3] + t * b[:3, 3]
            poses.append(T)
            key_index.append(k if i == n else k - 1)
    return np.stack(poses), np.asarray(key_index)


def arc(T0: FloatArray, point: ArrayLike, direction: ArrayLike, angle: float, step_rad: float):
    """Poses sweeping ``T0`` by ``angle`` about a line (see :func:`rotate_about_axis`)."""
    n = max(1, int(np.ceil(abs(angle) / step_rad)))
    return np.stack([rotate_about_axis(T0, point, direction, angle * i / n) for i in range(n + 1)])
